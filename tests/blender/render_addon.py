"""Renders a take the add-on generated on a Rigify human metarig (Cycles on the CPU, no
display needed) as a strip of frames: how docs/blender.png was made. The metarig has no mesh,
so each body bone gets a capsule parented to it.

    /tmp/bpy/bin/python tests/blender/render_addon.py GLOCAL MODEL TIMELINE out.png [frames]
"""
import os
import sys
import tempfile

import bpy
from mathutils import Matrix, Vector

import check_addon
import render_gltf

# Bones named so (the breasts, the fingers, the heel and pelvis guides) get no capsule, nor
# do the face's bones under the head, which gets a ball.
SKIPPED = ("breast", "palm", "thumb", "f_index", "f_middle", "f_ring", "f_pinky", "heel", "pelvis")
HEAD = "spine.006"
MIN_BONE = 0.03
# The seed tests/blender.rs generates with, so the picture is the take the README measures.
SEED = 2


def capsules(arm):
    """A capsule along every body bone longer than MIN_BONE, carried by its bone."""
    material = bpy.data.materials.new("body")
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.2, 0.42, 0.75, 1)
    arm.data.pose_position = "REST"
    bpy.context.view_layer.update()
    face = {b.name for b in arm.data.bones[HEAD].children_recursive}
    for bone in arm.data.bones:
        if bone.length < MIN_BONE or bone.name in face or any(bone.name.startswith(s) for s in SKIPPED):
            continue
        radius = 0.08 if bone.name.startswith("spine") else min(0.06, max(0.025, 0.16 * bone.length))
        if bone.name == HEAD:
            bpy.ops.mesh.primitive_uv_sphere_add(radius=0.1)
        else:
            bpy.ops.mesh.primitive_cylinder_add(radius=radius, depth=bone.length, vertices=12)
        piece = bpy.context.active_object
        piece.data.materials.append(material)
        if bone.name != HEAD:
            piece.modifiers.new("round", "BEVEL").width = radius * 0.6
        head, tail = arm.matrix_world @ bone.head_local, arm.matrix_world @ bone.tail_local
        placed = Matrix.Translation((head + tail) / 2) @ (tail - head).to_track_quat("Z", "Y").to_matrix().to_4x4()
        piece.parent, piece.parent_type, piece.parent_bone = arm, "BONE", bone.name
        bpy.context.view_layer.update()
        piece.matrix_world = placed
    arm.data.pose_position = "POSE"


def main(binary, model, timeline, out_path, count=4):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scratch = tempfile.mkdtemp(prefix="glocal-render-")
    check_addon.install_addon(scratch, binary)
    bpy.context.scene.glocal.model = model
    bpy.context.scene.glocal.seed = SEED
    arm = check_addon.rigify_metarig()
    check_addon.select_only(arm)
    bpy.ops.glocal.generate(timeline=timeline)
    capsules(arm)
    scene = bpy.context.scene
    camera = render_gltf.stage(scene)
    frames = render_gltf.render_strip(scene, arm, camera, scene.frame_start, scene.frame_end, int(count), out_path)
    print(f"{out_path}: frames {frames} of '{timeline}' on the Rigify metarig")
    sys.stdout.flush()
    os._exit(0)  # as check_addon: bpy 4.2 can crash tearing down after Rigify


if __name__ == "__main__":
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    main(*sys.argv[1:])
