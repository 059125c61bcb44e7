"""Opens exported .glb files in Blender's own glTF importer and compares them with the same
take exported as JSON: the skeleton (bone names and parents), a skinned mesh, the frame count,
and every joint's position in every frame, within 1% of the body's height.

Needs Blender as a Python module (see import_checks.SETUP), then:
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.glb
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.json
    /tmp/bpy/bin/python tests/blender/check_gltf_import.py take.glb take.json [more pairs...]
"""
import json

import bpy
from mathutils import Vector

from import_checks import imported_frames, main, passed, skeleton_failures


def gltf_point(v):
    """Blender's importer turns glTF's Y-up into Z-up: (x, y, z) -> (x, -z, y)."""
    return Vector((v.x, v.z, -v.y))


def check(glb_path, json_path, tolerance=None):
    """True when the glTF matches the JSON; joint positions within `tolerance` metres when
    given, else within 1% of the body's height."""
    take = json.load(open(json_path))
    unit = take["meters_per_unit"]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    # The importer places keyframes by the scene's frame rate: set it to the take's, as a
    # user would, so that frames map one to one.
    scene.render.fps, scene.render.fps_base = int(round(take["fps"])), 1.0
    bpy.ops.import_scene.gltf(filepath=glb_path)
    arm = next(o for o in scene.objects if o.type == "ARMATURE")
    meshes = [o for o in scene.objects if o.type == "MESH"]
    names = take["joints"]
    bones = arm.data.bones
    failures = skeleton_failures(bones, take)
    skinned = [m for m in meshes if any(mod.type == "ARMATURE" for mod in m.modifiers)]
    if not skinned:
        failures.append("no mesh skinned to the armature")
    first, frames = imported_frames(arm, take, failures)
    heights = [max(p[1] for p in f) - min(p[1] for p in f) for f in take["frames"]]
    height = max(heights) * unit
    worst, lowest = 0.0, float("inf")
    for f, joints in enumerate(take["frames"]):
        scene.frame_set(int(first) + f)
        for name, p in zip(names, joints):
            head = gltf_point(arm.matrix_world @ arm.pose.bones[name].head)
            worst = max(worst, (head - Vector(p) * unit).length)
            lowest = min(lowest, head.y)
    print(f"{glb_path}: {len(bones)} bones, {len(skinned)} skinned mesh, {frames} frames at {take['fps']:g} fps, "
          f"largest joint position difference {worst * 1000:.4f} mm (body height {height:.2f} m, "
          f"{100 * worst / height:.3f}%), lowest joint at {lowest * 1000:.2f} mm")
    limit = tolerance if tolerance is not None else 0.01 * height
    if worst > limit:
        failures.append(f"joint positions differ by up to {worst} m, over {limit} m")
    if abs(lowest) > 0.01 * height:
        failures.append(f"the lowest joint is at height {lowest} m, not on the floor")
    return passed(failures)


if __name__ == "__main__":
    main(check, __doc__)
