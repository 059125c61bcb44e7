"""Drives the Blender add-on (integrations/blender) in Blender itself: installs it from a zip
as a user would, generates onto a Rigify human metarig and onto a Mixamo-named armature built
here (lying in its own y-up space at 0.01 scale, as Mixamo FBX files import), and checks each
take against the same generation exported as JSON with Mixamo names:

- the new Action has the take's frame count and the scene its frame rate and range;
- every mapped bone points within 5 degrees of the take's (mean over the take). A bone the
  rig's pelvis or chest carries rigidly (its hips to a thigh's head, its chest to a collar's)
  is compared with where the take's pelvis or chest turn carries the rig's own rest bone:
  the take's own joint pair is another shape (Human3.6M's hip sockets are level with its hips
  joint and its collars start at its neck; the metarig's sockets sit 6 cm above its pelvis
  bone, 37.6 degrees off the take's pair before anything moves), which no turn of a rigid
  piece changes. Both pieces' turns are read from the same lines on both skeletons: side to
  side (right to left hip socket, shoulder socket) and up (hips to chest, chest to neck), the
  chest's side-to-side line at rest the hip sockets' (as motion/retarget/body.rs reads them);
- where the take's foot is planted, the rig's foot is within 2 cm of the floor, and its
  ankle moves across the floor as the take's does (scaled by the legs' ratio) within 1 cm;
- no mapped bone keeps an identity track while the take's joint moves;
- a pose marker of the Action names each segment where it starts;
- Continue from the armature starts the take from the armature's own last seconds, where it
  stood, or from its pose where it has no action;
- the add-on's Export FBX re-imports with the same frame count and every bone's turn from its
  rest pose within 0.5 degrees;
- a glocal error (a wrong class) is reported as one line and the armature keeps its actions.

Then the same take exported with `--joint-names mixamo` as BVH and glTF opens in Blender's
importers with the Mixamo names and every joint within 0.01 mm of the JSON export.

    /tmp/bpy/bin/python tests/blender/check_addon.py GLOCAL MODEL TIMELINE SEED TAKE.json TAKE.bvh TAKE.glb OUTDIR
(tests/blender.rs runs it; TAKE.* are `glocal generate --joint-names mixamo` of TIMELINE, SEED.)
"""
import json
import os
import shutil
import sys
from math import degrees, radians

import bpy
import addon_utils  # after bpy, which puts Blender's modules on the path
from mathutils import Matrix, Vector

import check_bvh_import
import check_gltf_import
from import_checks import SETUP, passed

ADDON = os.path.join(os.path.dirname(__file__), "..", "..", "integrations", "blender", "glocal_blender")
# Each mapped bone: (key joint at its start, key joint at its end), as retargeting maps them.
BONES = [("Hips", "Chest"), ("Chest", "Neck"), ("Neck", "Head")] + [
    pair for side in ("Left", "Right") for pair in [
        ("Chest", f"{side}Shoulder"), (f"{side}Shoulder", f"{side}Arm"), (f"{side}Arm", f"{side}ForeArm"),
        (f"{side}ForeArm", f"{side}Hand"), ("Hips", f"{side}UpLeg"), (f"{side}UpLeg", f"{side}Leg"),
        (f"{side}Leg", f"{side}Foot"), (f"{side}Foot", f"{side}ToeBase")]]
RIGIFY_KEYS = {"Hips": "spine", "Chest": "spine.003", "Neck": "spine.005", "Head": "spine.006", **{
    f"{side}{key}": f"{bone}.{side[0]}" for side in ("Left", "Right") for key, bone in [
        ("Shoulder", "shoulder"), ("Arm", "upper_arm"), ("ForeArm", "forearm"), ("Hand", "hand"),
        ("UpLeg", "thigh"), ("Leg", "shin"), ("Foot", "foot"), ("ToeBase", "toe")]}}
MIXAMO_KEYS = {key: f"mixamorig:{key}" for pair in BONES for key in pair} | {"Chest": "mixamorig:Spine2"}
# The rigid pieces of the trunk: (right, left) side-to-side line, (lower, upper) up line, and
# which of the two the piece's frame keeps exactly (as motion/retarget/body.rs reads them).
PIECES = {"Hips": (("RightUpLeg", "LeftUpLeg"), ("Hips", "Chest"), "side"),
          "Chest": (("RightArm", "LeftArm"), ("Chest", "Neck"), "up")}


def install_addon(out_dir, binary):
    """The add-on zipped and installed through Blender's preferences, as a user installs it."""
    archive = shutil.make_archive(os.path.join(out_dir, "glocal_blender"), "zip", os.path.dirname(ADDON), "glocal_blender")
    bpy.ops.preferences.addon_install(filepath=archive, overwrite=True)
    addon_utils.enable("glocal_blender", default_set=True)
    bpy.context.preferences.addons["glocal_blender"].preferences.binary = binary


def rigify_metarig():
    addon_utils.enable("rigify", default_set=True)
    bpy.ops.object.armature_human_metarig_add()
    return bpy.context.active_object


# A Mixamo-like T-pose in metres (z up, facing -y): bone -> (parent, head); tails at the
# first child's head, leaves pointing on along their parent's bone.
MIXAMO_REST = {
    "Hips": (None, (0, 0, 1.0)), "Spine": ("Hips", (0, 0, 1.1)), "Spine1": ("Spine", (0, 0, 1.22)),
    "Spine2": ("Spine1", (0, 0, 1.34)), "Neck": ("Spine2", (0, 0, 1.5)), "Head": ("Neck", (0, 0, 1.6)),
    "HeadTop_End": ("Head", (0, 0, 1.8)),
    **{name: (parent, (sign * x, y, z)) for side, sign in (("Left", 1), ("Right", -1)) for name, parent, (x, y, z) in [
        (f"{side}Shoulder", "Spine2", (0.05, 0, 1.45)), (f"{side}Arm", f"{side}Shoulder", (0.18, 0, 1.45)),
        (f"{side}ForeArm", f"{side}Arm", (0.45, 0, 1.45)), (f"{side}Hand", f"{side}ForeArm", (0.7, 0, 1.45)),
        (f"{side}UpLeg", "Hips", (0.09, 0, 0.95)), (f"{side}Leg", f"{side}UpLeg", (0.09, 0, 0.52)),
        (f"{side}Foot", f"{side}Leg", (0.09, 0, 0.08)), (f"{side}ToeBase", f"{side}Foot", (0.09, -0.12, 0.02)),
        (f"{side}Toe_End", f"{side}ToeBase", (0.09, -0.2, 0.02))]},
}


def mixamo_armature():
    """MIXAMO_REST with `mixamorig:` names, stored as a Mixamo FBX imports: armature space
    y up in centimetres, the object turned 90 degrees about x and scaled 0.01."""
    data = bpy.data.armatures.new("mixamo")
    arm = bpy.data.objects.new("mixamo", data)
    bpy.context.scene.collection.objects.link(arm)
    arm.rotation_euler = (radians(90), 0, 0)
    arm.scale = (0.01, 0.01, 0.01)
    select_only(arm)
    bpy.ops.object.mode_set(mode="EDIT")
    to_armature = Matrix.Rotation(radians(-90), 3, "X") * 100.0
    heads = {n: to_armature @ Vector(p) for n, (_, p) in MIXAMO_REST.items()}
    bones = {}
    for name, (parent, _) in MIXAMO_REST.items():
        bone = data.edit_bones.new(f"mixamorig:{name}")
        children = [c for c, (p, _) in MIXAMO_REST.items() if p == name]
        bone.head = heads[name]
        bone.tail = heads[children[0]] if children else heads[name] + (heads[name] - heads[parent]).normalized() * 8
        if parent:
            bone.parent = bones[parent]
        bones[name] = bone
    bpy.ops.object.mode_set(mode="OBJECT")
    return arm


def select_only(obj):
    for o in bpy.context.scene.objects:
        o.select_set(o == obj)
    bpy.context.view_layer.objects.active = obj


def existing_action(arm):
    """An action the user made before: a key on the first bone."""
    bone = arm.pose.bones[0]
    bone.rotation_mode = "QUATERNION"
    bone.rotation_quaternion = (0.9, 0.1, 0, 0)
    bone.keyframe_insert("rotation_quaternion", frame=1)
    action = arm.animation_data.action
    action.name = "Before"
    return action


def action_state(action):
    return [(c.data_path, c.array_index, [tuple(k.co) for k in c.keyframe_points]) for c in action.fcurves]


def native_keys(take):
    """Key joint -> index in the JSON take (Mixamo names; the chest is the spine's top)."""
    index = {n: j for j, n in enumerate(take["joints"])}
    keys = {key: index[f"mixamorig:{key}"] for pair in BONES for key in pair if f"mixamorig:{key}" in index}
    keys["Chest"] = take["parents"][index["mixamorig:LeftShoulder"]]
    return keys


def blender_point(p):
    """glocal's y-up world in Blender's z-up one (as the add-on's BVH files turn it)."""
    return Vector((p[0], -p[2], p[1]))


def piece_frame(points, piece, at_rest=False):
    """The frame of a rigid piece of the trunk from its key joints' `points` (a rotation)."""
    (right, left), (low, high), exact = PIECES[piece]
    if at_rest:
        right, left = PIECES["Hips"][0]
    side, up = points[left] - points[right], points[high] - points[low]
    forward = side.cross(up).normalized()
    if exact == "side":
        x = side.normalized()
        y = forward.cross(x)
    else:
        y = up.normalized()
        x = y.cross(forward)
    return Matrix((x, y, forward)).transposed()


def carried_bones(arm, keys):
    """The mapped bones the rig's pelvis or chest carries rigidly: (piece, end key) where the
    end key's bone hangs straight off the piece's bone."""
    return {(a, b) for a, b in BONES if a in PIECES and arm.data.bones[keys[b]].parent.name == keys[a]}


def check_generated(arm, keys, take, label, failures):
    """Frames, rate, bone directions, feet and moving tracks of the generated action."""
    scene = bpy.context.scene
    action = arm.animation_data.action
    frames = len(take["frames"])
    first, last = action.frame_range
    fps = scene.render.fps / scene.render.fps_base
    if (int(round(last - first)) + 1, scene.frame_start, scene.frame_end) != (frames, 1, frames):
        failures.append(f"{label}: action frames {first}-{last}, scene {scene.frame_start}-{scene.frame_end}, take {frames}")
    if abs(fps - take["fps"]) > 1e-4:
        failures.append(f"{label}: scene fps {fps}, take {take['fps']}")
    source = native_keys(take)
    rest = {key: arm.matrix_world @ arm.data.bones[bone].head_local for key, bone in keys.items()}
    rest_frames = {piece: piece_frame(rest, piece, at_rest=True) for piece in PIECES}
    carried = carried_bones(arm, keys)
    angles = {pair: [] for pair in BONES}
    own_pair = {pair: [] for pair in carried}
    source_turn = {pair: 0.0 for pair in BONES}
    track_turn = {pair: 0.0 for pair in BONES}
    lowest = {side: [] for side in ("left", "right")}
    ankles = {side: [] for side in lowest}
    feet = {side: foot_bones(arm, keys[f"{side.title()}Foot"]) for side in lowest}
    first_dirs = {}
    for f in range(frames):
        scene.frame_set(f + 1)
        heads = {key: arm.matrix_world @ arm.pose.bones[bone].head for key, bone in keys.items()}
        points = [blender_point(p) for p in take["frames"][f]]
        turns = {piece: piece_frame({k: points[j] for k, j in source.items()}, piece) @ rest_frames[piece].transposed() for piece in PIECES}
        for pair in BONES:
            a, b = pair
            want = points[source[b]] - points[source[a]]
            got = heads[b] - heads[a]
            if pair in carried:
                own_pair[pair].append(degrees(got.angle(want)))
                want = turns[a] @ (rest[b] - rest[a])
            angles[pair].append(degrees(got.angle(want)))
            first_dirs.setdefault(pair, want)
            source_turn[pair] = max(source_turn[pair], degrees(want.angle(first_dirs[pair])))
            basis = arm.pose.bones[keys[a]].matrix_basis.to_quaternion()
            track_turn[pair] = max(track_turn[pair], degrees(basis.angle))
        for side, bones in feet.items():
            if take["contacts"][f"{side}_foot"][f]:
                foot = f"{side.title()}Foot"
                ankles[side].append((f, heads[foot], points[source[foot]]))
                lowest[side].append(min(min((arm.matrix_world @ arm.pose.bones[b].head).z, (arm.matrix_world @ arm.pose.bones[b].tail).z) for b in bones))
    means = {pair: sum(v) / len(v) for pair, v in angles.items()}
    worst = max(means, key=means.get)
    moving = [pair for pair in BONES if source_turn[pair] > 1.0]
    planted = [z for side in lowest.values() for z in side]
    floor = max(abs(z) for z in planted) if planted else float("nan")
    slide = planted_slide(ankles, leg_ratio(arm, keys, take, source))
    shown = sorted(p for p in carried if "Right" not in p[1])
    print(f"{label}: action '{action.name}', {frames} frames at {fps:g} fps (scene {scene.frame_start}-{scene.frame_end}); "
          f"{len(means)} mapped bones against the take's directions (mean over the take): worst {worst[0]}->{worst[1]} {means[worst]:.2f} deg, "
          f"mean {sum(means.values()) / len(means):.2f} deg; carried by the pelvis and chest: "
          f"{', '.join(f'{a}->{b} {means[(a, b)]:.2f}' for a, b in shown)} deg "
          f"(against the take's own joint pair {', '.join(f'{sum(own_pair[p]) / len(own_pair[p]):.1f}' for p in shown)}); "
          f"{sum(track_turn[p] >= 1e-3 for p in moving)} of {len(moving)} moving bones keyed off identity; "
          f"planted feet {len(planted)} foot-frames, farthest from the floor {100 * floor:.2f} cm, "
          f"their ankles at most {100 * slide:.2f} cm across the floor from the take's within a contact")
    for pair, mean in means.items():
        if mean > 5.0:
            failures.append(f"{label}: bone {pair[0]}->{pair[1]} is {mean:.2f} deg from the take's on average")
        if source_turn[pair] > 1.0 and track_turn[pair] < 1e-3:
            failures.append(f"{label}: bone {keys[pair[0]]} keeps an identity track while the take's {pair[0]} turns {source_turn[pair]:.1f} deg")
    if not planted or floor > 0.02:
        failures.append(f"{label}: planted feet up to {floor} m from the floor")
    if slide > 0.01:
        failures.append(f"{label}: a planted ankle slides {100 * slide:.2f} cm from the take's within a contact")


def leg_ratio(arm, keys, take, source):
    """The rig's leg (thigh and shin at rest, in the scene's units) over the take's."""
    legs = (("LeftUpLeg", "LeftLeg"), ("LeftLeg", "LeftFoot"))
    bones = arm.data.bones
    rig = sum((bones[keys[b]].head_local - bones[keys[a]].head_local).length for a, b in legs)
    points = [blender_point(p) for p in take["frames"][0]]
    own = sum((points[source[b]] - points[source[a]]).length for a, b in legs)
    return arm.matrix_world.to_scale()[0] * rig / own


def planted_slide(ankles, ratio):
    """Within each run of planted frames, the farthest the rig's ankle moves across the
    floor other than the take's ankle does, scaled by the legs' ratio (a heel rolling onto
    its toes carries both ankles)."""
    slide = 0.0
    for frames in ankles.values():
        start = None
        for k, (f, rig, take) in enumerate(frames):
            if k == 0 or f != frames[k - 1][0] + 1:
                start = (rig, take)
            moved = (rig - start[0]) - ratio * (take - start[1])
            slide = max(slide, Vector((moved.x, moved.y)).length)
    return slide


def foot_bones(arm, foot):
    bone = arm.data.bones[foot]
    return [foot] + [b.name for b in bone.children_recursive]


def check_fbx(arm, out_dir, label, failures):
    """Export FBX, import it back, compare frame counts and every bone's turn from rest."""
    path = os.path.join(out_dir, f"{label}.fbx")
    select_only(arm)
    bpy.ops.glocal.export_fbx(filepath=path)
    before = set(bpy.context.scene.objects)
    # No frame offset: the importer's default shifts the keys one frame on.
    bpy.ops.import_scene.fbx(filepath=path, anim_offset=0)
    back = next(o for o in bpy.context.scene.objects if o not in before and o.type == "ARMATURE")
    first, last = arm.animation_data.action.frame_range
    got = back.animation_data.action.frame_range
    if tuple(got) != (first, last):
        failures.append(f"{label}: the FBX re-imports with frames {tuple(got)}, exported {(first, last)}")
    worst = 0.0
    for f in range(int(first), int(last) + 1):
        bpy.context.scene.frame_set(f)
        for bone in arm.pose.bones:
            other = back.pose.bones[bone.name]
            worst = max(worst, degrees(turn(arm, bone).rotation_difference(turn(back, other)).angle))
    print(f"{label}: FBX re-imported with frames {got[0]:g}-{got[1]:g} ({int(got[1] - got[0]) + 1}), "
          f"largest bone rotation difference {worst:.4f} deg over {len(arm.pose.bones)} bones")
    if worst > 0.5:
        failures.append(f"{label}: FBX bone rotations differ by up to {worst:.3f} deg")
    bpy.data.objects.remove(back)


def turn(arm, pose_bone):
    """The bone's rotation in the world. (Not from its rest: the FBX importer takes an
    armature's rest from the file's bone nodes, which the exporter writes in the pose.)"""
    return (arm.matrix_world @ pose_bone.matrix).to_3x3().normalized().to_quaternion()


def check_error(arm, before, label, failures):
    """A wrong class: one line of error, and the armature's actions as they were."""
    actions = set(bpy.data.actions)
    state = action_state(before)
    try:
        bpy.ops.glocal.generate(timeline="flying:4")
        failures.append(f"{label}: a wrong class generated")
        return
    except RuntimeError as e:
        message = str(e).strip()
    print(f"{label}: wrong class reported as: {message}")
    if len(message.splitlines()) != 1 or "flying" not in message:
        failures.append(f"{label}: the error is not one line naming the class: {message!r}")
    if arm.animation_data.action != before or set(bpy.data.actions) != actions or action_state(before) != state:
        failures.append(f"{label}: the armature's actions changed on an error")


def run_rig(rig, timeline, seed, take, out_dir, failures):
    label, make, keys = rig
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for action in list(bpy.data.actions):
        bpy.data.actions.remove(action)
    arm = make()
    select_only(arm)
    # A scene at the model's frame rate, where the take's frames are the JSON export's.
    bpy.context.scene.render.fps, bpy.context.scene.render.fps_base = round(take["fps"]), 1.0
    before = existing_action(arm)
    state = action_state(before)
    check_error(arm, before, label, failures)
    settings = bpy.context.scene.glocal
    settings.seed = seed
    settings.segments.clear()
    for part in timeline.split(","):
        activity, seconds = part.split(":")
        row = settings.segments.add()
        row.activity, row.seconds = activity, float(seconds)
    bpy.ops.glocal.generate()
    if arm.animation_data.action.name != timeline:
        failures.append(f"{label}: the new action is '{arm.animation_data.action.name}', not named after the timeline")
    if before.name not in bpy.data.actions or action_state(before) != state:
        failures.append(f"{label}: the armature's earlier action changed")
    check_generated(arm, keys, take, label, failures)
    check_markers(arm.animation_data.action, take, label, failures)
    check_fbx(arm, out_dir, label, failures)
    check_scene_rate(arm, take, label, failures)
    check_continue(arm, label, failures)


def check_markers(action, take, label, failures):
    """A pose marker names each segment of the take at its first frame (Blender's frames
    count from 1)."""
    want = [(s["name"] + (f"/{s['style']}" if s.get("style") else ""), s["start_frame"] + 1) for s in take["segments"]]
    got = [(m.name, m.frame) for m in sorted(action.pose_markers, key=lambda m: m.frame)]
    if got != want or len(want) < 2:
        failures.append(f"{label}: pose markers {got}, the take's segments {want}")
    else:
        print(f"{label}: pose markers {got}")


def check_scene_rate(arm, take, label, failures):
    """Generate in a scene at 30 fps (a game's rate, not the model's): the scene keeps it,
    and the take comes at it, as long in seconds as at the model's rate; the test's take is
    put back after."""
    select_only(arm)
    scene = bpy.context.scene
    before = arm.animation_data.action
    scene.render.fps = 30
    bpy.ops.glocal.generate(timeline="walking:2")
    new = arm.animation_data.action
    fps = scene.render.fps / scene.render.fps_base
    frames = int(new.frame_range[1] - new.frame_range[0]) + 1
    print(f"{label}: generated in a 30 fps scene: {frames} frames, scene {scene.frame_start}-{scene.frame_end} at {fps:g} fps")
    if fps != 30 or abs((frames - 1) / 30 - 2.0) > 0.1 or scene.frame_end != frames:
        failures.append(f"{label}: a 2 s take in a 30 fps scene has {frames} frames, the scene {fps:g} fps to frame {scene.frame_end}")
    scene.render.fps = round(take["fps"])
    arm.animation_data.action = before


def check_continue(arm, label, failures):
    """Generate with Continue from the armature, the scene at 24 fps (a film's rate, not the
    model's): one new Action, the armature's own up to the current frame (every bone where it
    was, to a hundredth of a degree, the root to a tenth of a millimetre), then the take at the
    scene's rate (which stays 24 fps), turning no bone more in one frame over the half second
    after the join than the armature's own did over the seconds before it (glocal keeps a start
    retargeted back onto its own rig as the rig's frames: `synth::own_start`); the take's first
    segment marked on the frame after the join; the armature's Action as it was; and from a
    pose without an action ([`check_from_a_pose`])."""
    from glocal_blender import properties
    select_only(arm)
    scene, settings = bpy.context.scene, bpy.context.scene.glocal
    info = properties.model_info(settings.model)
    scene.render.fps, scene.render.fps_base = 24, 1.0
    old = arm.animation_data.action
    state = action_state(old)
    bones = [b.name for b in arm.pose.bones if b.bone.use_deform or b.parent is None]

    def pose(action, frame):
        arm.animation_data.action = action
        scene.frame_set(frame)
        world = arm.matrix_world
        return {n: (world @ arm.pose.bones[n].tail - world @ arm.pose.bones[n].head).normalized() for n in bones}, world @ arm.pose.bones[bones[0]].head

    def largest_turn(action, frames):
        """The most any bone turns from one of `frames` to the next."""
        dirs = [pose(action, k)[0] for k in frames]
        return max(degrees(a[n].angle(b[n])) for a, b in zip(dirs, dirs[1:]) for n in bones if a[n].length > 0 and b[n].length > 0)

    current = scene.frame_start + round(info["start_seconds"] * 24) + 20
    scene.frame_set(current)
    settings.continue_action = True
    try:
        if "FINISHED" not in bpy.ops.glocal.generate(timeline="walking:3"):
            failures.append(f"{label}: Continue from the armature did not generate")
            return
        new = arm.animation_data.action
        angles, apart = [], 0.0
        for k in range(scene.frame_start, current + 1):
            (after, root_after), (before, root_before) = pose(new, k), pose(old, k)
            angles += [degrees(before[n].angle(after[n])) for n in bones if before[n].length > 0 and after[n].length > 0]
            apart = max(apart, (root_after - root_before).length)
        own, after_join = largest_turn(old, range(current - 48, current + 1)), largest_turn(new, range(current, current + 13))
        end = int(new.frame_range[1])
        markers = sorted((m.frame, m.name) for m in new.pose_markers if m.frame > current)
        fps = scene.render.fps / scene.render.fps_base
        print(f"{label}: continued from frame {current} at {fps:g} fps into '{new.name}', frames {int(new.frame_range[0])}-{end}: up to the join every bone within {max(angles):.4f} deg, root {1000 * apart:.3f} mm; "
              f"largest bone turn in a frame over the half second after the join {after_join:.1f} deg, over the armature's two seconds before {own:.1f}; markers {markers}")
        if max(angles) > 0.01 or apart > 1e-4:
            failures.append(f"{label}: the continued Action is {max(angles):.4f} deg and {1000 * apart:.3f} mm off the armature's before the join")
        if after_join > 1.5 * own:
            failures.append(f"{label}: a bone turns {after_join:.1f} deg in one frame after the join, the armature's at most {own:.1f}")
        if fps != 24 or scene.frame_end != end or (end - current) / fps < 1.0:
            failures.append(f"{label}: the continued take runs to frame {end} at {fps:g} fps (scene range to {scene.frame_end})")
        if not markers or markers[0] != (current + 1, "walking"):
            failures.append(f"{label}: the continued take's markers are {markers}")
        if action_state(old) != state:
            failures.append(f"{label}: the armature's Action changed")
        check_refusals(arm, old, label, failures)
        check_continue_keyed(arm, old, pose, bones, label, failures)
        check_from_a_pose(arm, new, pose, bones, label, failures)
    finally:
        settings.continue_action = False


def check_continue_keyed(arm, source, pose, bones, label, failures):
    """Continue from animations keyed by hand: `source`'s poses keyed on every bone at a few
    frames, Blender's own Bezier curves with automatic handles; the current frame between two
    keys, or before the first (the animation holding its first pose there). The new Action up
    to the current frame is that animation to a hundredth of a degree, though its keys after
    the current frame are gone and the last one before it has a new neighbour (or, keyed on
    the current frame, keys after it)."""
    scene = bpy.context.scene
    for keys in ((1, 20, 40, 60, 80), (1, 20, 40, 69), (80, 100)):
        keyed = bpy.data.actions.new("keyed by hand")
        for frame in keys:
            arm.animation_data.action = source
            scene.frame_set(frame)
            posed = {b.name: (b.location.copy(), b.rotation_quaternion.copy(), b.rotation_euler.copy()) for b in arm.pose.bones}
            arm.animation_data.action = keyed
            for b in arm.pose.bones:
                b.location, b.rotation_quaternion, b.rotation_euler = posed[b.name]
                b.keyframe_insert("location", frame=frame)
                b.keyframe_insert("rotation_quaternion" if b.rotation_mode == "QUATERNION" else "rotation_euler", frame=frame)
        current = 69
        scene.frame_set(current)
        if "FINISHED" not in bpy.ops.glocal.generate(timeline="walking:3"):
            failures.append(f"{label}: Continue from a keyed animation did not generate")
            return
        new = arm.animation_data.action
        worst, apart = 0.0, 0.0
        for k in range(1, current + 1):
            (after, root_after), (before, root_before) = pose(new, k), pose(keyed, k)
            worst = max([worst] + [degrees(before[n].angle(after[n])) for n in bones if before[n].length > 0 and after[n].length > 0])
            apart = max(apart, (root_after - root_before).length)
        print(f"{label}: continued from frame {current} of an animation keyed at frames {keys}: up to the join every bone within {worst:.4f} deg, root {1000 * apart:.3f} mm")
        if worst > 0.01 or apart > 1e-4:
            failures.append(f"{label}: continuing an animation keyed at {keys} moved it by {worst:.4f} deg and {1000 * apart:.3f} mm before the join")
        for act in (keyed, new):
            bpy.data.actions.remove(act)
        arm.animation_data.action = source


def check_refusals(arm, act, label, failures):
    """Continuations that cannot be made are refused in one line before glocal runs, the
    armature's actions as they were: a timeline ending before the current frame, a first row
    at another pace, an Action with a curve modifier."""
    arm.animation_data.action = act
    for timeline, modifier, says in (("walking:1", False, "needs more than"), ("walking:3@1.5", False, "pace"), ("walking:3", True, "modifiers")):
        curve = act.fcurves[0]
        if modifier:
            curve.modifiers.new("NOISE")
        actions, state = set(bpy.data.actions), action_state(act)
        try:
            bpy.ops.glocal.generate(timeline=timeline)
            failures.append(f"{label}: continuing with {timeline}{' and a modifier' if modifier else ''} generated")
            continue
        except RuntimeError as e:
            message = str(e).strip()
        finally:
            if modifier:
                curve.modifiers.remove(curve.modifiers[0])
        print(f"{label}: continuing with {timeline}{' and a curve modifier' if modifier else ''} refused: {message}")
        if len(message.splitlines()) != 1 or says not in message or set(bpy.data.actions) != actions or action_state(act) != state or arm.animation_data.action != act:
            failures.append(f"{label}: continuing with {timeline}: {message!r}, actions changed or kept")


def check_from_a_pose(arm, action, pose, bones, label, failures):
    """An armature without an action continues from its current pose: the take holds it
    over its start (frames 1-25 within 1 degree, every bone; root within 2 cm) and then
    moves."""
    scene = bpy.context.scene
    (posed, root_posed) = pose(action, 30)
    arm.animation_data.action = None
    scene.frame_set(1)
    if "FINISHED" not in bpy.ops.glocal.generate(timeline="walking:4"):
        failures.append(f"{label}: continuing from a pose did not generate")
        return
    new = arm.animation_data.action
    worst, apart = 0.0, 0.0
    for k in range(1, 26):
        (after, root_after) = pose(new, k)
        worst = max([worst] + [degrees(posed[n].angle(after[n])) for n in bones if posed[n].length > 0 and after[n].length > 0])
        apart = max(apart, (root_after - root_posed).length)
    (_, root_end) = pose(new, int(new.frame_range[1]))
    print(f"{label}: continued from a pose: frames 1-25 within {worst:.2f} deg of it, root within {100 * apart:.2f} cm; then {(root_end - root_posed).length:.2f} m on")
    if worst > 1.0 or apart > 0.02 or (root_end - root_posed).length < 0.5:
        failures.append(f"{label}: a take from a pose: frames 1-25 {worst:.2f} deg and {100 * apart:.2f} cm off it, {(root_end - root_posed).length:.2f} m walked")


def check_styles(model, failures):
    """A row's style goes into the timeline on the model of everything (`models/all` beside
    the test's model); a model without styles offers only the usual one."""
    from glocal_blender import properties
    settings = bpy.context.scene.glocal
    offered = [item[0] for item in properties.style_items(None, bpy.context)]
    if offered != [properties.USUAL]:
        failures.append(f"{model}: a model without styles offers {offered}")
    settings.model = os.path.join(os.path.dirname(os.path.normpath(model)), "all")
    settings.segments.clear()
    row = settings.segments.add()
    row.activity, row.style, row.seconds = "walking", "happy", 4.0
    settings.segments.add().activity = "salsa"
    text = properties.timeline_text(settings)
    if text != "walking/happy:4,salsa:4":
        failures.append(f"the rows on models/all make the timeline '{text}'")
    else:
        print(f"styles: the rows make {text}")
    settings.model = model


def check_mixamo_names(bvh, glb, json_path, failures):
    names = json.load(open(json_path))["joints"]
    if not all(n.startswith("mixamorig:") for n in names) or not {"mixamorig:Hips", "mixamorig:LeftArm", "mixamorig:RightUpLeg"} <= set(names):
        failures.append(f"--joint-names mixamo wrote {names}")
    if not check_bvh_import.check(bvh, json_path, tolerance=1e-5):
        failures.append(f"{bvh}: the Mixamo-named BVH does not import within 0.01 mm")
    if not check_gltf_import.check(glb, json_path, tolerance=1e-5):
        failures.append(f"{glb}: the Mixamo-named glTF does not import within 0.01 mm")


# (label, builder, key joint -> bone).
RIGS = [("rigify", rigify_metarig, RIGIFY_KEYS), ("mixamo", mixamo_armature, MIXAMO_KEYS)]


def main(binary, model, timeline, seed, json_path, bvh, glb, out_dir):
    take = json.load(open(json_path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    install_addon(out_dir, binary)
    bpy.context.scene.glocal.model = model
    failures = []
    for rig in RIGS:
        run_rig(rig, timeline, int(seed), take, out_dir, failures)
    check_styles(model, failures)
    # Last: these reset Blender to its factory settings.
    check_mixamo_names(bvh, glb, json_path, failures)
    ok = passed(failures)
    sys.stdout.flush()
    # Straight out: bpy 4.2 can crash tearing down after Rigify has been enabled.
    os._exit(0 if ok else 1)


if __name__ == "__main__":
    if len(sys.argv) != 9:
        sys.exit(f"{__doc__}\n{SETUP}")
    main(*sys.argv[1:])
