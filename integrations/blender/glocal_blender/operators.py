"""Generate (glocal in the background, the take onto the selected armature as a new Action),
Export FBX, and the timeline's add / remove row buttons."""
import math

import bpy
from bpy_extras.io_utils import ExportHelper
from mathutils import Matrix

from . import action, bvh_io, properties, runner
from .preferences import glocal_binary

# Blender's FBX exporter, set for what Unreal's and Unity's importers take without changes:
# metres scaled into the file's unit (FBX_SCALE_ALL), y up and -z forward (both importers
# convert from it), bones along +Y, no extra leaf bones (they would show as joints in the
# engines), the active action baked over the scene's range with a key on every frame and no
# simplification, so the engine plays exactly the frames Blender shows.
FBX_SETTINGS = {
    "use_selection": True,
    "object_types": {"ARMATURE", "MESH"},
    "apply_unit_scale": True,
    "apply_scale_options": "FBX_SCALE_ALL",
    "axis_forward": "-Z",
    "axis_up": "Y",
    "primary_bone_axis": "Y",
    "secondary_bone_axis": "X",
    "add_leaf_bones": False,
    "use_armature_deform_only": False,
    "bake_anim": True,
    "bake_anim_use_all_bones": True,
    "bake_anim_use_nla_strips": False,
    "bake_anim_use_all_actions": False,
    "bake_anim_force_startend_keying": True,
    "bake_anim_step": 1.0,
    "bake_anim_simplify_factor": 0.0,
}


def selected_armature(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "ARMATURE" and obj.select_get() else None


class GLOCAL_OT_generate(bpy.types.Operator):
    """Generate the timeline with glocal onto the selected armature, as a new Action"""

    bl_idname = "glocal.generate"
    bl_label = "Generate"
    bl_options = {"REGISTER", "UNDO"}

    timeline: bpy.props.StringProperty(
        name="Timeline", default="", options={"SKIP_SAVE"},
        description="A --timeline text (CLASS:SECONDS[@PACE],...) in place of the panel's rows, for scripts")

    _run = None
    _timer = None

    @classmethod
    def poll(cls, context):
        return selected_armature(context) is not None and not context.scene.glocal.running

    def start(self, context):
        """Starts glocal; False (with the reason reported) when it cannot be started."""
        settings = context.scene.glocal
        binary = glocal_binary(context)
        if binary is None:
            self.report({"ERROR"}, "glocal binary not found: set its path in the add-on's preferences")
            return False
        if properties.model_info(settings.model) is None:
            self.report({"ERROR"}, f"model folder '{settings.model}' has no readable model.json")
            return False
        self.text = self.timeline or properties.timeline_text(settings)
        if not self.text:
            self.report({"ERROR"}, "the timeline is empty: add a row")
            return False
        self.arm = selected_armature(context)
        try:
            self.continued = Continued(context.scene, self.arm, properties.model_info(settings.model), self.text) if settings.continue_action else None
            start = self.continued.bvh if self.continued else None
            fps = context.scene.render.fps / context.scene.render.fps_base
            self._run = runner.Run(binary, bpy.path.abspath(settings.model), self.text, settings.seed, self.arm, fps, start)
        except (OSError, ValueError) as e:
            self.report({"ERROR"}, str(e))
            return False
        settings.running, settings.progress, settings.status = True, 0.0, "Generating…"
        self.expected = STARTUP_SECONDS + take_seconds(self.text) * SECONDS_PER_TAKE_SECOND
        return True

    def finish(self, context):
        """Puts the finished take on the armature; the operator's return value."""
        settings = context.scene.glocal
        settings.running, settings.progress, settings.status = False, 0.0, ""
        try:
            take = self._run.result()
        except (RuntimeError, OSError, ValueError) as e:
            self.report({"ERROR"}, str(e).splitlines()[0] if str(e) else "glocal failed")
            return {"CANCELLED"}
        # Keying a long take on a big rig takes a while too: the cursor shows how far it is.
        wm = context.window_manager
        wm.progress_begin(0, 100)
        progress = lambda done: wm.progress_update(int(100 * done))
        if self.continued:
            self.continued.place(take)
            self.continued.put_on_armature(context.scene, self.arm, take, self.text, progress)
        else:
            put_on_armature(context.scene, self.arm, take, self.text, progress)
        wm.progress_end()
        self.report({"INFO"}, f"{self.text}: {take.frames} frames at {take.fps:g} fps on {self.arm.name}")
        return {"FINISHED"}

    def execute(self, context):
        """Runs to the end (from scripts: no window, no progress)."""
        if not self.start(context):
            return {"CANCELLED"}
        return self.finish(context)  # reading glocal's output waits for it

    def invoke(self, context, event):
        if not self.start(context):
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        settings = context.scene.glocal
        if event.type == "ESC":
            self.stop_timer(context)
            self._run.cancel()
            settings.running, settings.status = False, ""
            self.report({"WARNING"}, "generation cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if not self._run.poll():
            elapsed = self._run.elapsed()
            # glocal shows no progress through a pipe: an estimate from the take's length, held
            # at 95% if it runs longer.
            settings.progress = min(0.95, elapsed / self.expected)
            settings.status = f"Generating… {elapsed:.1f} s (Esc cancels)"
            for area in context.screen.areas:
                area.tag_redraw()
            return {"RUNNING_MODAL"}
        self.stop_timer(context)
        return self.finish(context)

    def stop_timer(self, context):
        context.window_manager.event_timer_remove(self._timer)


class Continued:
    """The armature's own animation a take continues (Continue from the armature): the seconds
    a take's start reads, ending at the current frame (or a fraction of a frame after it),
    sampled at the model's frame rate as a BVH; the scene frame the take's first frame falls
    on (a whole one: the take comes at the scene's frame rate, counted from there);
    and where the armature's root stands then. An armature without an action continues from
    its current pose, the take beginning at the current frame and holding it over its start;
    an action that starts later than those seconds holds its first pose before it, as
    Blender shows it."""

    def __init__(self, scene, arm, info, timeline):
        """Raises ValueError, with what to change, for a continuation that cannot be made: an
        Action with curve modifiers, a first row at another pace than 1 (its start would not be
        the armature's own timing), a timeline ending before the current frame."""
        fps = scene.render.fps / scene.render.fps_base
        self.action = arm.animation_data.action if arm.animation_data else None
        self.current = scene.frame_current
        step = info["stride"] / info["fps"]
        # From the take's first frame (a sparse step into its start) to the end of its start.
        lead = info["start_seconds"] - step
        # The start ends at the current frame or up to a frame after it (a scene rate a hair
        # under a whole number, as Blender's single-precision base gives, counts as that number).
        self.first = self.current - (math.floor(lead * fps + 1e-3) if self.action else 0)
        self.check(timeline, (self.current - self.first) / fps, fps)
        begin = self.first - step * fps
        samples = [begin + i * fps / info["fps"] for i in range(round(info["start_seconds"] * info["fps"]) + 1)]
        self.bvh = bvh_io.posed_bvh(arm, scene, samples, info["fps"])
        self.root = bvh_io.root_turn(arm, scene, self.first)

    def check(self, timeline, before, fps):
        """See [`__init__`]; `before`: the take's seconds up to the current frame."""
        modified = action.modified_curves(self.action) if self.action else []
        if modified:
            raise ValueError(f"'{self.action.name}' has {len(modified)} curve{'s' if len(modified) > 1 else ''} with modifiers (first {modified[0]}): apply or remove them to continue it")
        if first_pace(timeline) != 1.0:
            raise ValueError(f"the first row's pace is {first_pace(timeline):g}: continuing from the armature needs pace 1, the armature's own timing")
        if (take_seconds(timeline) - before) * fps < 1.0:
            raise ValueError(f"the timeline is {take_seconds(timeline):g} s: continuing from the current frame needs more than {before:.2f} s, which the take spends on the armature's own seconds")

    def place(self, take):
        """Turns `take` about the vertical and moves it so that its root stands at its first
        frame where the armature's stood (glocal starts a take from a file at the origin,
        facing +z)."""
        turn, position = self.root
        yaw = bvh_io.heading(turn) - bvh_io.heading(take.rotations[0][0])
        spin = Matrix.Rotation(yaw, 3, "Z")
        shift = position - spin @ take.positions[0][0]
        take.rotations = [[spin @ r for r in frame] for frame in take.rotations]
        take.positions = [[spin @ p + shift for p in frame] for frame in take.positions]

    def put_on_armature(self, scene, arm, take, name, progress):
        """The armature's Action up to the current frame, then the take, as a new Action (the
        old one kept, with a fake user); the take's segments marked where they begin after the
        current frame; the scene's range run to the take's end. With no action to continue, the
        take from the current frame, and the scene's range from it."""
        if self.action is None:
            new = action.new_action(arm, take, name, progress, first=self.first)
        else:
            new = action.continued_action(arm, self.action, take, f"{self.action.name} + {name}", self.first, self.current, progress)
        for label, first in take.segments:
            new.pose_markers.new(label).frame = max(self.first + first, self.current + 1 if self.action else self.first)
        use_action(arm, new)
        if self.action is None:
            scene.frame_start = self.first
        scene.frame_end = self.first + take.frames - 1
        scene.frame_set(self.current)


# For the progress estimate: `glocal generate` took 0.18 s for a 7 s h36m take and 0.44 s for
# a 60 s one, retargeted onto the 159-bone Rigify metarig (2 CPU cores).
STARTUP_SECONDS = 0.15
SECONDS_PER_TAKE_SECOND = 0.005


def _timing(part):
    """The seconds and pace of one segment of a --timeline text (CLASS:SECONDS[@PACE][~T]),
    as numbers: None where one is not given or not a number."""
    seconds, _, pace = part.rpartition(":")[2].split("~")[0].partition("@")

    def number(text):
        try:
            return float(text)
        except ValueError:
            return None

    return number(seconds), number(pace)


def first_pace(timeline):
    """The pace of a --timeline text's first segment, 1 unless given."""
    pace = _timing(timeline.split(",")[0])[1]
    return 1.0 if pace is None else pace


def take_seconds(timeline):
    """The length a timeline text asks for (its segments' seconds, comma-separated)."""
    return sum((seconds for seconds, _ in map(_timing, timeline.split(",")) if seconds is not None), 0.0)


def put_on_armature(scene, arm, take, name, progress):
    """The take as a new Action on `arm` (its previous action kept, with a fake user so it is
    saved), a pose marker naming each segment where it starts, the scene's range set to the
    take's (its frame rate, which the take was made at, kept)."""
    new = action.new_action(arm, take, name, progress)
    # Markers of the Action, not the scene: they go with the take (the Action Editor shows
    # them with View > Show Pose Markers) and leave the user's own scene markers alone.
    for label, first in take.segments:
        new.pose_markers.new(label).frame = first + 1
    use_action(arm, new)
    scene.frame_start, scene.frame_end = 1, take.frames
    scene.frame_set(1)


def use_action(arm, new):
    """Makes `new` the armature's action, its previous one kept with a fake user."""
    if arm.animation_data is None:
        arm.animation_data_create()
    previous = arm.animation_data.action
    if previous is not None:
        previous.use_fake_user = True
    arm.animation_data.action = new


class GLOCAL_OT_export_fbx(bpy.types.Operator, ExportHelper):
    """Export the selected armature and its action as FBX, set for Unreal and Unity"""

    bl_idname = "glocal.export_fbx"
    bl_label = "Export FBX"
    filename_ext = ".fbx"
    filter_glob: bpy.props.StringProperty(default="*.fbx", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        arm = selected_armature(context)
        return arm is not None and arm.animation_data is not None and arm.animation_data.action is not None

    def execute(self, context):
        result = bpy.ops.export_scene.fbx(filepath=self.filepath, **FBX_SETTINGS)
        if "FINISHED" not in result:
            self.report({"ERROR"}, f"{self.filepath}: the FBX exporter did not finish")
            return {"CANCELLED"}
        self.report({"INFO"}, f"wrote {self.filepath}")
        return {"FINISHED"}


class GLOCAL_OT_segment_add(bpy.types.Operator):
    """Add a row to the timeline"""

    bl_idname = "glocal.segment_add"
    bl_label = "Add segment"

    def execute(self, context):
        settings = context.scene.glocal
        settings.segments.add()
        settings.active_segment = len(settings.segments) - 1
        return {"FINISHED"}


class GLOCAL_OT_segment_remove(bpy.types.Operator):
    """Remove the selected row of the timeline"""

    bl_idname = "glocal.segment_remove"
    bl_label = "Remove segment"

    @classmethod
    def poll(cls, context):
        return len(context.scene.glocal.segments) > 0

    def execute(self, context):
        settings = context.scene.glocal
        settings.segments.remove(settings.active_segment)
        settings.active_segment = max(0, min(settings.active_segment, len(settings.segments) - 1))
        return {"FINISHED"}


_classes = (GLOCAL_OT_generate, GLOCAL_OT_export_fbx, GLOCAL_OT_segment_add, GLOCAL_OT_segment_remove)


register, unregister = bpy.utils.register_classes_factory(_classes)
