"""Writes tests/assets/blender-unreal-salsa.bvh: a CMU salsa clip as Blender's own BVH exporter
writes it for an Unreal-mannequin-named rig, so the retarget tests read a file from an
exporter other than ours.

Needs Blender as a Python module (not part of `cargo test`; about 400 MB):
    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy
    tar -I zstd -xOf /work/shared/data/cmu-dance.tar.zst cmu-dance/salsa/01.bvh > /tmp/salsa01.bvh
    /tmp/bpy/bin/python tests/blender/make_foreign_bvh.py /tmp/salsa01.bvh tests/assets/blender-unreal-salsa.bvh

What it does, all with Blender's own tools:
- imports the clip with Blender's BVH importer into a 60 fps scene (the header says 120 fps,
  so the importer's frame-rate scaling keeps every second a second, with half the frames);
  the axes are left as they are (forward Y, up Z: the identity), because Blender's exporter
  writes armature space with no axis conversion, so the file stays Y-up like its source;
- copies the armature and edits the copy's rest pose: Unreal mannequin names (pelvis,
  spine_01, clavicle_l, upperarm_l, lowerarm_l, thigh_l, calf_l, foot_l, ...), the eyes,
  fingers and CMU's hip joints (lButtock, never rotated in the clip) deleted, a `ball_l`/
  `ball_r` toe bone added, a `root` bone on the floor above the pelvis, the whole rest lifted
  to stand on the floor and the arms lowered 45 degrees into an A-pose;
- drives every renamed bone with a world-space Copy Transforms constraint from its source
  bone, so the copy moves exactly as the clip does on its new rest pose;
- exports the copy with `bpy.ops.export_anim.bvh` and its defaults (native Euler orders, XYZ
  for the new bones, position channels on every bone not connected to its parent) over 240
  frames (4 s from source frame 1200 of the 120 fps header).
"""
import sys
from math import radians

import bpy
from mathutils import Matrix, Vector

FPS = 60
FIRST, FRAMES = 601, 240
A_POSE_DEGREES = 45.0

# CMU (acLSTM) name -> Unreal mannequin name; source bones not listed are deleted.
UNREAL_NAMES = {
    "hip": "pelvis",
    "abdomen": "spine_01",
    "chest": "spine_02",
    "neck": "neck_01",
    "head": "head",
    **{f"{s}Collar": f"clavicle_{s}" for s in "lr"},
    **{f"{s}Shldr": f"upperarm_{s}" for s in "lr"},
    **{f"{s}ForeArm": f"lowerarm_{s}" for s in "lr"},
    **{f"{s}Hand": f"hand_{s}" for s in "lr"},
    **{f"{s}Thigh": f"thigh_{s}" for s in "lr"},
    **{f"{s}Shin": f"calf_{s}" for s in "lr"},
    **{f"{s}Foot": f"foot_{s}" for s in "lr"},
}


def import_clip(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.render.fps = FPS
    bpy.ops.import_anim.bvh(filepath=path, axis_forward="Y", axis_up="Z", rotate_mode="NATIVE", use_fps_scale=True)
    return bpy.context.view_layer.objects.active


def unreal_copy(source):
    rig = source.copy()
    rig.data = source.data.copy()
    rig.animation_data_clear()
    rig.name = rig.data.name = "mannequin"
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    bones = rig.data.edit_bones
    for bone in [b for b in bones if b.name not in UNREAL_NAMES]:
        bones.remove(bone)  # its children move to its parent
    for bone in list(bones):
        bone.name = UNREAL_NAMES[bone.name]
    floor = min(min(b.head.y, b.tail.y) for b in bones)
    for bone in bones:
        bone.transform(Matrix.Translation((0.0, -floor, 0.0)))
    for side in "lr":
        add_ball(bones, bones[f"foot_{side}"])
        lower_arm(bones, bones[f"upperarm_{side}"], side)
    root = bones.new("root")
    root.head, root.tail = Vector((0, 0, 0)), Vector((0, 0, 10))
    bones["pelvis"].parent = root
    bpy.ops.object.mode_set(mode="OBJECT")
    return rig


def add_ball(bones, foot):
    """A toe bone from the ball of the foot (the foot bone's end) forward along the floor."""
    ball = bones.new(foot.name.replace("foot", "ball"))
    ahead = Vector((foot.vector.x, 0.0, foot.vector.z)).normalized()
    ball.head, ball.tail = foot.tail, foot.tail + ahead * 0.5 * foot.length
    ball.parent, ball.use_connect = foot, True


def lower_arm(bones, upper, side):
    """Turns the arm from the shoulder joint about the forward axis (z), hand downwards."""
    angle = radians(-A_POSE_DEGREES if upper.tail.x > upper.head.x else A_POSE_DEGREES)
    about = Matrix.Translation(upper.head) @ Matrix.Rotation(angle, 4, "Z") @ Matrix.Translation(-upper.head)
    for bone in [upper, *upper.children_recursive]:
        bone.transform(about)


def follow(rig, source):
    renamed = {unreal: cmu for cmu, unreal in UNREAL_NAMES.items()}
    for bone in rig.pose.bones:
        if bone.name in renamed:
            c = bone.constraints.new("COPY_TRANSFORMS")
            c.target, c.subtarget = source, renamed[bone.name]
            c.target_space = c.owner_space = "WORLD"


def main(clip_path, out_path):
    source = import_clip(clip_path)
    rig = unreal_copy(source)
    follow(rig, source)
    for o in bpy.context.view_layer.objects:
        o.select_set(o == rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.export_anim.bvh(filepath=out_path, frame_start=FIRST, frame_end=FIRST + FRAMES - 1)


if __name__ == "__main__":
    main(*sys.argv[1:3])
