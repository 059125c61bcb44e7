"""A take put on an armature as an Action: for every bone the take has, the local transform
(location and rotation, in the bone's own rotation mode) that puts the bone where the take's
joint is and turns it as the take's joint turns from the rest pose. A new Action of the take
alone, or the take after the current frame of a copy of the armature's own Action."""
import bpy
from mathutils import Euler, Matrix, Quaternion


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
    """A copy of the armature's Action `old`, its keys after scene frame `after` gone (a key
    at `after` holding what its curves gave there), then `take` keyed from scene frame
    `after + 1` on, its frame k falling on scene frame `first + k`; `old`'s pose markers
    after `after` go too. Returns the copy; `old` is not touched."""
    action = old.copy()
    action.name = name
    for curve in action.fcurves:
        _trim_after(curve, after)
    for marker in [m for m in action.pose_markers if m.frame > after]:
        action.pose_markers.remove(marker)
    frames = range(max(0, after + 1 - first), take.frames)
    tracks = bone_tracks(arm, take, frames, progress)
    for bone_name, bases in tracks.items():
        _key_bone(action, arm.pose.bones[bone_name], bases, first + frames.start, after)
    return action


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


def _trim_after(curve, frame):
    """Cuts `curve` after scene frame `frame`, keeping every whole frame up to it as it was:
    its keys after `frame` go, the frames between its last key before and `frame` (or `frame`
    alone, where every key was after it) are keyed with the values the curve gave them (linear
    keys, which the take's keys follow), and that last key's handles are frozen where they
    were (an automatic handle would turn towards the new neighbour and reshape the curve
    before it)."""
    points = curve.keyframe_points
    kept = [p for p in points if p.co.x <= frame]
    if kept and kept[-1].co.x == frame and len(kept) == len(points):
        return
    between = range(int(kept[-1].co.x) + 1 if kept else int(frame), int(frame) + 1)
    values = [curve.evaluate(f) for f in between]
    if kept:
        kept[-1].handle_left_type = kept[-1].handle_right_type = "FREE"
        kept[-1].interpolation = "LINEAR"
    for point in reversed([p for p in points if p.co.x > frame]):
        points.remove(point, fast=True)
    for f, value in zip(between, values):
        points.insert(f, value, options={"FAST"}).interpolation = "LINEAR"
    curve.update()


def _key_bone(action, pose_bone, bases, first, after=None):
    """Keys `bases` on `pose_bone` from scene frame `first` on, after the keys its curves in
    `action` have (curves made where it has none), linear; rotations continue from the value
    at scene frame `after` of its curves there, if given, so a quaternion does not flip sign
    across the join."""
    path = f'pose.bones["{bpy.utils.escape_identifier(pose_bone.name)}"]'
    locations = [b.to_translation() for b in bases]
    mode = pose_bone.rotation_mode
    if mode == "QUATERNION":
        rotation = "rotation_quaternion"
        before = _value_at(action, f"{path}.{rotation}", 4, after)
        values = _continuous_quaternions(bases, Quaternion(before) if before else None)
    elif mode == "AXIS_ANGLE":
        rotation = "rotation_axis_angle"
        values = [(q.angle, *q.axis) for q in _continuous_quaternions(bases)]
    else:
        rotation = "rotation_euler"
        before = _value_at(action, f"{path}.{rotation}", 3, after)
        values = _continuous_eulers(bases, mode, Euler(before, mode) if before else None)
    for prop, rows in (("location", locations), (rotation, values)):
        data_path = f"{path}.{prop}"
        for axis in range(len(rows[0])):
            curve = action.fcurves.find(data_path, index=axis)
            if curve is None:
                curve = action.fcurves.new(data_path, index=axis, action_group=pose_bone.name)
                if after is not None:
                    # A bone the Action did not animate stood as posed: it does up to the join.
                    curve.keyframe_points.insert(after, getattr(pose_bone, prop)[axis], options={"FAST"}).interpolation = "LINEAR"
            keys = curve.keyframe_points
            old = len(keys)
            coords, kinds = [0.0] * (2 * old), [0] * old
            keys.foreach_get("co", coords)
            keys.foreach_get("interpolation", kinds)
            keys.add(len(rows))
            keys.foreach_set("co", coords + [c for f, row in enumerate(rows) for c in (first + f, row[axis])])
            keys.foreach_set("interpolation", kinds + [LINEAR] * len(rows))
            curve.update()


def _value_at(action, data_path, width, frame):
    """The values of `action`'s curves of `data_path` at `frame`, or None where it has none."""
    if frame is None:
        return None
    curves = [action.fcurves.find(data_path, index=axis) for axis in range(width)]
    if any(c is None for c in curves):
        return None
    return [c.evaluate(frame) for c in curves]


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
