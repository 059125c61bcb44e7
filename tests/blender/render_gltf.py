"""Renders a .glb take in Blender (Cycles on the CPU, no display needed) as a strip of frames:
how docs/gltf_take.png was made.

    /tmp/bpy/bin/python tests/blender/render_gltf.py take.glb out.png [frames per strip]
"""
import math
import sys

import bpy
import numpy as np
from mathutils import Vector

WIDTH, HEIGHT = 320, 400


def setup(glb_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_scene.gltf(filepath=glb_path)
    arm = next(o for o in scene.objects if o.type == "ARMATURE")
    first, last = arm.animation_data.action.frame_range
    camera = stage(scene)
    return scene, arm, camera, int(first), int(last)


def stage(scene):
    """Floor, sun, sky, camera and Cycles on the CPU around whatever the scene holds."""
    bpy.ops.mesh.primitive_plane_add(size=40)
    floor = bpy.context.active_object
    floor_material = bpy.data.materials.new("floor")
    floor_material.diffuse_color = (0.85, 0.86, 0.88, 1)
    floor_material.use_nodes = True
    floor_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.55, 0.56, 0.58, 1)
    floor.data.materials.append(floor_material)
    bpy.ops.object.light_add(type="SUN", rotation=(math.radians(40), math.radians(10), math.radians(30)))
    bpy.context.active_object.data.energy = 3.5
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.9, 0.92, 0.95, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.5
    scene.world = world
    bpy.ops.object.camera_add()
    camera = bpy.context.active_object
    camera.data.lens = 50
    scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 24
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.film_transparent = False
    return camera


def render_frame(scene, arm, camera, frame, path):
    scene.frame_set(frame)
    hips = arm.matrix_world @ arm.pose.bones[0].head
    target = Vector((hips.x, hips.y, 0.8))
    camera.location = target + Vector((1.6, -2.9, 0.35))
    camera.rotation_euler = (target - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path)
    pixels = np.array(image.pixels[:], dtype=np.float32).reshape(HEIGHT, WIDTH, 4)
    bpy.data.images.remove(image)
    return pixels


def render_strip(scene, arm, camera, first, last, count, out_path):
    """`count` frames spread over first..last side by side in one PNG; the frames drawn."""
    frames = [round(first + (last - first) * (k + 0.5) / count) for k in range(count)]
    strip = np.concatenate([render_frame(scene, arm, camera, f, f"/tmp/render_gltf_{f}.png") for f in frames], axis=1)
    image = bpy.data.images.new("strip", WIDTH * count, HEIGHT)
    image.pixels = strip.ravel()
    # Saved through the scene's settings, an RGB PNG at full compression for a small file; the
    # frames already went through the view transform, so the strip goes through none.
    settings = scene.render.image_settings
    settings.file_format, settings.color_mode, settings.compression = "PNG", "RGB", 100
    scene.view_settings.view_transform = "Standard"
    image.save_render(out_path, scene=scene)
    return frames


def main(glb_path, out_path, count):
    frames = render_strip(*setup(glb_path), count, out_path)
    print(f"{out_path}: frames {frames} of {glb_path}")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 4)
