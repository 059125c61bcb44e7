"""The panel's settings, kept on the scene: the model folder, the timeline rows, the seed,
and the state of a running generation."""
import json
import os

import bpy

_model_cache = {}


def model_info(folder):
    """The `classes`, `styles` and `fps` of the model.json in `folder`, and the seconds of
    motion a take's start reads (`start_seconds`), or None when it has none to read; read
    once per folder and file time."""
    path = os.path.join(bpy.path.abspath(folder), "model.json")
    try:
        stamp = os.path.getmtime(path)
    except OSError:
        return None
    cached = _model_cache.get(path)
    if cached and cached[0] == stamp:
        return cached[1]
    try:
        with open(path) as f:
            spec = json.load(f)
        info = {"classes": list(spec.get("classes", [])), "styles": list(spec.get("styles", [])), "fps": spec.get("fps"),
                "stride": spec["stride"],
                "start_seconds": spec["stride"] * spec["block_len"] / spec["fps"]}
    except (OSError, ValueError, KeyError, TypeError, ZeroDivisionError):
        info = None
    _model_cache[path] = (stamp, info)
    return info


# Blender shows garbage when an items callback's strings are freed: keep every list made.
_items_cache = {}


def class_items(self, context):
    info = model_info(context.scene.glocal.model) if context else None
    classes = tuple(info["classes"]) if info else ()
    if classes not in _items_cache:
        _items_cache[classes] = [(c, c, "") for c in classes] or [("NONE", "(no model)", "")]
    return _items_cache[classes]


# A row without a style of its own: its activity's usual one (the model's `usual_styles`).
USUAL = "USUAL"


def style_items(self, context):
    info = model_info(context.scene.glocal.model) if context else None
    styles = tuple(info["styles"]) if info else ()
    key = ("styles",) + styles
    if key not in _items_cache:
        usual = (USUAL, "usual style", "The style most of this activity's training clips have")
        _items_cache[key] = [usual] + [(s, s, "") for s in styles]
    return _items_cache[key]


class GlocalSegment(bpy.types.PropertyGroup):
    activity: bpy.props.EnumProperty(name="Class", items=class_items)
    style: bpy.props.EnumProperty(name="Style", items=style_items, description="The style of this activity (models with styles)")
    seconds: bpy.props.FloatProperty(name="Seconds", default=4.0, min=0.5, max=600.0, precision=1)
    pace: bpy.props.FloatProperty(name="Pace", default=1.0, min=0.1, max=10.0, precision=2,
                                  description="2.0 plays the same poses over twice the time")


class GlocalSettings(bpy.types.PropertyGroup):
    model: bpy.props.StringProperty(name="Model", subtype="DIR_PATH", default="",
                                    description="A glocal model folder (with model.json), e.g. models/h36m")
    segments: bpy.props.CollectionProperty(type=GlocalSegment)
    active_segment: bpy.props.IntProperty(default=0)
    seed: bpy.props.IntProperty(name="Seed", default=0, min=0, description="0: the model's own take; others vary it")
    continue_action: bpy.props.BoolProperty(
        name="Continue from the armature", default=False,
        description="Start from the armature's own motion in the seconds before the current frame (as many as the model reads: 2 s on the shipped models; its current pose, held, where it has no animation), which the take begins with, instead of the model's own start")
    running: bpy.props.BoolProperty(default=False)
    progress: bpy.props.FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    status: bpy.props.StringProperty(default="")


def timeline_text(settings):
    """The `--timeline` argument the rows describe: CLASS[/STYLE]:SECONDS[@PACE],
    comma-separated."""
    parts = []
    for s in settings.segments:
        style = "" if s.style == USUAL else f"/{s.style}"
        part = f"{s.activity}{style}:{s.seconds:g}"
        if abs(s.pace - 1.0) > 1e-6:
            part += f"@{s.pace:g}"
        parts.append(part)
    return ",".join(parts)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory((GlocalSegment, GlocalSettings))


def register():
    _register_classes()
    bpy.types.Scene.glocal = bpy.props.PointerProperty(type=GlocalSettings)


def unregister():
    del bpy.types.Scene.glocal
    _unregister_classes()
