"""Opens exported BVH files in Blender's own BVH importer and compares them with the same
take exported as JSON: skeleton (bone names and parents), length, frame rate, and every
joint's position in every frame.

Needs Blender as a Python module (see import_checks.SETUP), then:
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.bvh
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.json
    /tmp/bpy/bin/python tests/blender/check_bvh_import.py take.bvh take.json [more pairs...]
"""
import json

import bpy
from mathutils import Vector

from import_checks import imported_frames, main, passed, skeleton_failures


def check(bvh_path, json_path, tolerance=None):
    """True when the BVH matches the JSON; joint positions within `tolerance` metres when
    given, else within 0.1% of the skeleton's extent."""
    take = json.load(open(json_path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    # Forward Y, up Z: the importer's identity conversion, so positions compare one to one
    # with the JSON's (a user keeps the default, which turns the file's Y-up into Z-up).
    bpy.ops.import_anim.bvh(filepath=bvh_path, axis_forward="Y", axis_up="Z", rotate_mode="NATIVE",
                            update_scene_fps=True, update_scene_duration=True)
    arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    scene = bpy.context.scene
    names = take["joints"]
    bones = arm.data.bones
    failures = skeleton_failures(bones, take)
    first, frames = imported_frames(arm, take, failures)
    fps = scene.render.fps / scene.render.fps_base
    if abs(fps - take["fps"]) > 1e-3:
        failures.append(f"scene fps {fps}, take {take['fps']}")
    worst, lowest = 0.0, float("inf")
    scale = max(Vector(p).length for p in take["frames"][0])
    for f, joints in enumerate(take["frames"]):
        scene.frame_set(int(first) + f)
        for name, p in zip(names, joints):
            head = arm.matrix_world @ arm.pose.bones[name].head
            worst = max(worst, (head - Vector(p)).length)
            lowest = min(lowest, head.y)
    units = "mm" if abs(take["meters_per_unit"] - 0.001) < 1e-9 else f"x {take['meters_per_unit']} m"
    print(f"{bvh_path}: {len(bones)} bones, {frames} frames at {fps:g} fps, "
          f"largest joint position difference {worst:.6f} ({units}; skeleton extent {scale:.0f}), "
          f"lowest joint at height {lowest:.4f}")
    limit = tolerance / take["meters_per_unit"] if tolerance is not None else 1e-3 * scale
    if worst > limit:
        failures.append(f"joint positions differ by up to {worst}")
    if abs(lowest) > 1e-3 * scale:
        failures.append(f"the lowest joint is at height {lowest}, not on the floor")
    return passed(failures)


if __name__ == "__main__":
    main(check, __doc__)
