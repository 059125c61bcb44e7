"""A take put on an armature as a new Action: for every bone the take has, the local
transform (location and rotation, in the bone's own rotation mode) that puts the bone where
the take's joint is and turns it as the take's joint turns from the rest pose."""
import bpy
from mathutils import Matrix


def new_action(arm, take, name, progress=lambda done: None):
    """Keys frames 1..N of a new Action from `take` (joints matched by bone name) and
    returns it; the armature's own actions are not touched. `progress` hears the fraction
    of frames done."""
    world_turn = arm.matrix_world.to_quaternion().to_matrix()
    to_armature = arm.matrix_world.inverted()
    index = {n: j for j, n in enumerate(take.names)}
    bones = [b for b in arm.data.bones if b.name in index]
    rest = {b.name: b.matrix_local for b in bones}
    tracks = {b.name: [] for b in bones}
    for f in range(take.frames):
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
        progress((f + 1) / take.frames)
    action = bpy.data.actions.new(name)
    for bone in bones:
        _key_bone(action, arm.pose.bones[bone.name], tracks[bone.name])
    return action


def _key_bone(action, pose_bone, bases):
    path = f'pose.bones["{bpy.utils.escape_identifier(pose_bone.name)}"]'
    locations = [b.to_translation() for b in bases]
    mode = pose_bone.rotation_mode
    if mode == "QUATERNION":
        rotation, values = "rotation_quaternion", _continuous_quaternions(bases)
    elif mode == "AXIS_ANGLE":
        rotation = "rotation_axis_angle"
        values = [(q.angle, *q.axis) for q in _continuous_quaternions(bases)]
    else:
        rotation, values = "rotation_euler", _continuous_eulers(bases, mode)
    for data_path, rows in ((f"{path}.location", locations), (f"{path}.{rotation}", values)):
        for axis in range(len(rows[0])):
            curve = action.fcurves.new(data_path, index=axis, action_group=pose_bone.name)
            curve.keyframe_points.add(len(rows))
            coords = [c for f, row in enumerate(rows) for c in (f + 1, row[axis])]
            curve.keyframe_points.foreach_set("co", coords)
            curve.keyframe_points.foreach_set("interpolation", [LINEAR] * len(rows))
            curve.update()


# The enum value of 'LINEAR' in a keyframe's interpolation.
LINEAR = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value


def _continuous_quaternions(bases):
    out = []
    for b in bases:
        q = b.to_quaternion()
        if out and q.dot(out[-1]) < 0:
            q.negate()
        out.append(q)
    return out


def _continuous_eulers(bases, order):
    out = []
    for b in bases:
        out.append(b.to_euler(order, out[-1]) if out else b.to_euler(order))
    return out
