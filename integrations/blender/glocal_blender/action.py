"""A take put on an armature as an Action: for every bone the take has, the local transform
(location and rotation, in the bone's own rotation mode) that puts the bone where the take's
joint is and turns it as the take's joint turns from the rest pose. A new Action of the take
alone, or the take after the current frame of a copy of the armature's own Action."""
from math import floor

import bpy
from mathutils import Matrix, Quaternion


def new_action(arm, take, name, progress=lambda done: None, first=1):
    """Keys scene frames `first`.. of a new Action with `take`'s frames (joints matched by
    bone name) and returns it; the armature's own actions are not touched. `progress` hears
    the fraction of frames done."""
    action = bpy.data.actions.new(name)
    tracks = bone_tracks(arm, take, range(take.frames), progress)
    for bone_name, bases in tracks.items():
        _key_bone(action, arm.pose.bones[bone_name], bases, first)
    return action


def continued_action(arm, old, take, name, first, after, progress=lambda done: None):
    """A copy of the armature's Action `old` cut after scene frame `after` (every whole frame
    up to it as it was: [`_cut_after`]), then `take` keyed from scene frame `after + 1` on,
    its frame k falling on scene frame `first + k`; `old`'s pose markers after `after` go
    too. The scene is to stand at `after` with `old` playing: the bones' values there are
    where the take's curves go on from. Returns the copy; `old` is not touched."""
    action = old.copy()
    action.name = name
    # A manual frame range on the Action would cut the take off at the old one's end.
    action.use_frame_range = False
    for curve in action.fcurves:
        _cut_after(curve, after)
    for marker in [m for m in action.pose_markers if m.frame > after]:
        action.pose_markers.remove(marker)
    frames = range(max(0, after + 1 - first), take.frames)
    tracks = bone_tracks(arm, take, frames, progress)
    for bone_name, bases in tracks.items():
        _key_bone(action, arm.pose.bones[bone_name], bases, first + frames.start, after)
    return action


def modified_curves(act):
    """`act`'s curves with modifiers (Noise, Cycles, ...), which a cut cannot keep as they
    were: the values they give are the modifiers' on the keys, and the take's keys after
    the cut would be modified too."""
    return [f"{c.data_path}[{c.array_index}] ({', '.join(m.type.lower() for m in c.modifiers)})" for c in act.fcurves if len(c.modifiers)]


def bone_tracks(arm, take, frames, progress=lambda done: None):
    """Per bone the take has, its local transform (basis matrix) at each of `frames`."""
    world_turn = arm.matrix_world.to_quaternion().to_matrix()
    to_armature = arm.matrix_world.inverted()
    index = {n: j for j, n in enumerate(take.names)}
    bones = [b for b in arm.data.bones if b.name in index]
    rest = {b.name: b.matrix_local for b in bones}
    tracks = {b.name: [] for b in bones}
    for done, f in enumerate(frames):
        posed = {}
        for bone in bones:  # parents come before their children in armature order
            j = index[bone.name]
            turn = world_turn.inverted() @ take.rotations[f][j] @ world_turn @ rest[bone.name].to_3x3()
            posed[bone.name] = Matrix.Translation(to_armature @ take.positions[f][j]) @ turn.to_4x4()
            parent = bone.parent
            if parent is not None and parent.name in posed:
                basis = (rest[parent.name].inverted() @ rest[bone.name]).inverted() @ posed[parent.name].inverted() @ posed[bone.name]
            else:
                basis = rest[bone.name].inverted() @ posed[bone.name]
            tracks[bone.name].append(basis)
        progress((done + 1) / len(frames))
    return tracks


def _cut_after(curve, frame):
    """Cuts `curve` after scene frame `frame`, keeping every whole frame up to it as it was
    and ready for keys after it: its keys after `frame` go; where one did, the frames between
    its last key before and `frame` (or `frame` alone, where every key was after it) are keyed
    with the values the curve gave them, linear; where none did, its last key holds its value
    up to a key at `frame`. That last key's handles are frozen where they were: an automatic
    handle turns towards a new neighbour and would reshape the curve before it."""
    points = curve.keyframe_points
    if not len(points):
        return
    kept = [p for p in points if p.co.x <= frame]
    if kept:
        kept[-1].handle_left_type = kept[-1].handle_right_type = "FREE"
    if len(kept) == len(points):
        # Held from the last key to `frame`, then on to the take's first key.
        if kept[-1].co.x < frame:
            kept[-1].interpolation = "CONSTANT"
            points.insert(frame, curve.evaluate(frame), options={"FAST"}).interpolation = "LINEAR"
        else:
            kept[-1].interpolation = "LINEAR"
        curve.update()
        return
    between = range(floor(kept[-1].co.x) + 1 if kept else frame, frame + 1)
    values = [curve.evaluate(f) for f in between]
    if kept:
        kept[-1].interpolation = "LINEAR"
    for point in reversed([p for p in points if p.co.x > frame]):
        points.remove(point, fast=True)
    for f, value in zip(between, values):
        points.insert(f, value, options={"FAST"}).interpolation = "LINEAR"
    curve.update()


def _key_bone(action, pose_bone, bases, first, after=None):
    """Keys `bases` on `pose_bone` from scene frame `first` on, after the keys its curves in
    `action` have (curves made where it has none), linear. With `after`, the take goes on
    from the bone's values now (the scene standing at `after`): a curve the Action did not
    have is keyed at `after` with the bone's value, as it stood, and the rotations continue
    from the bone's, so a quaternion or an axis and angle does not flip across the join."""
    path = f'pose.bones["{bpy.utils.escape_identifier(pose_bone.name)}"]'
    locations = [b.to_translation() for b in bases]
    mode = pose_bone.rotation_mode
    held = after is not None
    if mode == "QUATERNION":
        rotation = "rotation_quaternion"
        values = _continuous_quaternions(bases, pose_bone.rotation_quaternion.copy() if held else None)
    elif mode == "AXIS_ANGLE":
        rotation = "rotation_axis_angle"
        angle, *axis = pose_bone.rotation_axis_angle
        values = [(q.angle, *q.axis) for q in _continuous_quaternions(bases, Quaternion(axis, angle) if held else None)]
    else:
        rotation = "rotation_euler"
        values = _continuous_eulers(bases, mode, pose_bone.rotation_euler.copy() if held else None)
    for prop, rows in (("location", locations), (rotation, values)):
        data_path = f"{path}.{prop}"
        for axis in range(len(rows[0])):
            curve = action.fcurves.find(data_path, index=axis) or action.fcurves.new(data_path, index=axis, action_group=pose_bone.name)
            keys = curve.keyframe_points
            if held and not len(keys):
                # A bone the Action did not animate stood as posed: it does up to the join.
                keys.insert(after, getattr(pose_bone, prop)[axis], options={"FAST"}).interpolation = "LINEAR"
            old = len(keys)
            coords, kinds = [0.0] * (2 * old), [0] * old
            keys.foreach_get("co", coords)
            keys.foreach_get("interpolation", kinds)
            keys.add(len(rows))
            keys.foreach_set("co", coords + [c for f, row in enumerate(rows) for c in (first + f, row[axis])])
            keys.foreach_set("interpolation", kinds + [LINEAR] * len(rows))
            curve.update()


# The enum value of 'LINEAR' in a keyframe's interpolation.
LINEAR = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value


def _continuous_quaternions(bases, before=None):
    out = []
    for b in bases:
        q = b.to_quaternion()
        last = out[-1] if out else before
        if last is not None and q.dot(last) < 0:
            q.negate()
        out.append(q)
    return out


def _continuous_eulers(bases, order, before=None):
    out = []
    for b in bases:
        last = out[-1] if out else before
        out.append(b.to_euler(order, last) if last is not None else b.to_euler(order))
    return out
