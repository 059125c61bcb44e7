"""Opens exported .glb files in Blender's own glTF importer and compares them with the same
take exported as JSON: the skeleton (bone names and parents), a skinned mesh, the frame count,
and every joint's position in every frame, within 1% of the body's height.

Needs Blender as a Python module (not part of `cargo test`; about 400 MB):
    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.glb
    glocal generate --model models/h36m --timeline "walking:4,sitting:4" --out take.json
    /tmp/bpy/bin/python tests/blender/check_gltf_import.py take.glb take.json [more pairs...]
Exits non-zero when any check fails.
"""
import json
import sys

import bpy
from mathutils import Vector


def gltf_point(v):
    """Blender's importer turns glTF's Y-up into Z-up: (x, y, z) -> (x, -z, y)."""
    return Vector((v.x, v.z, -v.y))


def check(glb_path, json_path):
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
    skinned = [m for m in meshes if any(mod.type == "ARMATURE" for mod in m.modifiers)]
    if not skinned:
        failures.append("no mesh skinned to the armature")
    action = arm.animation_data.action
    first, last = action.frame_range
    frames = int(round(last - first)) + 1
    if frames != len(take["frames"]):
        failures.append(f"{frames} frames in Blender, {len(take['frames'])} exported")
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
          f"largest joint position difference {worst * 1000:.2f} mm (body height {height:.2f} m, "
          f"{100 * worst / height:.3f}%), lowest joint at {lowest * 1000:.2f} mm")
    if worst > 0.01 * height:
        failures.append(f"joint positions differ by up to {worst} m, over 1% of the body's height")
    if abs(lowest) > 0.01 * height:
        failures.append(f"the lowest joint is at height {lowest} m, not on the floor")
    for f in failures:
        print("  FAIL:", f)
    return not failures


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) < 2 or len(args) % 2:
        sys.exit(__doc__)
    ok = all([check(args[i], args[i + 1]) for i in range(0, len(args), 2)])
    sys.exit(0 if ok else 1)
