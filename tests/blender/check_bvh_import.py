"""Opens exported BVH files in Blender's own BVH importer and compares them with the same
take exported as JSON: skeleton (bone names and parents), length, frame rate, and every
joint's position in every frame.

Needs Blender as a Python module (not part of `cargo test`; about 400 MB):
    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.bvh
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.json
    /tmp/bpy/bin/python tests/blender/check_bvh_import.py take.bvh take.json [more pairs...]
Exits non-zero when any check fails.
"""
import json
import sys

import bpy
from mathutils import Vector


def check(bvh_path, json_path):
    take = json.load(open(json_path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    # Forward Y, up Z: the importer's identity conversion, so positions compare one to one
    # with the JSON's (a user keeps the default, which turns the file's Y-up into Z-up).
    bpy.ops.import_anim.bvh(filepath=bvh_path, axis_forward="Y", axis_up="Z", rotate_mode="NATIVE",
                            update_scene_fps=True, update_scene_duration=True)
    arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    scene = bpy.context.scene
    names, parents = take["joints"], take["parents"]
    bones = arm.data.bones
    failures = []
    if sorted(b.name for b in bones) != sorted(names):
        failures.append(f"bones {sorted(b.name for b in bones)} != joints {sorted(names)}")
    for name, parent in zip(names, parents):
        bone = bones.get(name)
        want = None if parent is None or parent < 0 else names[parent]
        got = bone.parent.name if bone and bone.parent else None
        if bone and got != want:
            failures.append(f"{name}: parent {got}, expected {want}")
    first, last = arm.animation_data.action.frame_range
    frames = int(round(last - first)) + 1
    if frames != len(take["frames"]):
        failures.append(f"{frames} frames in Blender, {len(take['frames'])} exported")
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
          f"largest joint position difference {worst:.4f} ({units}; skeleton extent {scale:.0f}), "
          f"lowest joint at height {lowest:.4f}")
    if worst > 1e-3 * scale:
        failures.append(f"joint positions differ by up to {worst}")
    if abs(lowest) > 1e-3 * scale:
        failures.append(f"the lowest joint is at height {lowest}, not on the floor")
    for f in failures:
        print("  FAIL:", f)
    return not failures


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) < 2 or len(args) % 2:
        sys.exit(__doc__)
    ok = all([check(args[i], args[i + 1]) for i in range(0, len(args), 2)])
    sys.exit(0 if ok else 1)
