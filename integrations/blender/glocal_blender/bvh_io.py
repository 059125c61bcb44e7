"""The two BVH files between Blender and glocal: the selected armature's rest pose and bone
names written for `--retarget-to`, and the take glocal writes back read into per-frame world
rotations and positions. BVH is y-up and Blender z-up: a point (x, y, z) in Blender's world is
(x, z, -y) in the file, the same turn Blender's own BVH importer undoes by default.

Both files are in world space (the armature object's location, rotation and scale applied),
so a rig imported lying in its own y-up space with a 0.01 scale (as Mixamo FBX files come in)
stands up and measures in metres for glocal like any other.
"""
from math import atan2, degrees, floor, radians

from mathutils import Matrix, Vector

# Blender world -> BVH file, and back.
TO_BVH = Matrix(((1, 0, 0), (0, 0, 1), (0, -1, 0)))
FROM_BVH = TO_BVH.transposed()
AXES = {"X": Vector((1, 0, 0)), "Y": Vector((0, 1, 0)), "Z": Vector((0, 0, 1))}


def rig_bvh(arm):
    """The armature's rest pose as a one-frame BVH: a joint at every bone's head, an end
    site at every leaf bone's tail. An armature with several root bones is refused."""
    lines, order = _hierarchy(arm)
    # The one frame is the rest pose: the root where its offset puts it, nothing turned.
    root = TO_BVH @ (arm.matrix_world @ order[0].head_local)
    rotations = " ".join(["0"] * 3 * len(order))
    lines.extend(["MOTION", "Frames: 1", "Frame Time: 0.04", f"{_xyz(root)} {rotations}"])
    return "\n".join(lines) + "\n"


def posed_bvh(arm, scene, frames, fps):
    """The armature as the scene poses it at each of `frames` (scene frame numbers, whole or
    not), on the rest hierarchy of [`rig_bvh`], as a BVH at `fps`: each joint's turn from its
    rest pose, the root's head where it stands."""
    lines, order = _hierarchy(arm)
    lines.extend(["MOTION", f"Frames: {len(frames)}", f"Frame Time: {1.0 / fps:.8f}"])
    current = scene.frame_current
    for f in frames:
        _frame_set(scene, f)
        # Each bone's turn from its rest pose, in the file's axes (a joint's world turn in a BVH).
        turns = {b.name: TO_BVH @ _world_turn(arm, b) @ FROM_BVH for b in order}
        values = [_xyz(TO_BVH @ (arm.matrix_world @ arm.pose.bones[order[0].name].head))]
        for bone in order:
            local = turns[bone.name] if bone.parent is None else turns[bone.parent.name].inverted() @ turns[bone.name]
            # Channels Z X Y: the turn is Rz Rx Ry, Blender's Euler order YXZ.
            e = local.to_euler("YXZ")
            values.append(f"{degrees(e.z):.6f} {degrees(e.x):.6f} {degrees(e.y):.6f}")
        lines.append(" ".join(values))
    scene.frame_set(current)
    return "\n".join(lines) + "\n"


def _frame_set(scene, frame):
    """Poses the scene at `frame`, a whole scene frame or between two."""
    whole = floor(frame)
    scene.frame_set(int(whole), subframe=frame - whole)


def root_turn(arm, scene, frame):
    """The armature's root bone at scene `frame`: its world turn from its rest pose and its
    head, in Blender's world (as [`read_take`] gives a take's joints)."""
    current = scene.frame_current
    _frame_set(scene, frame)
    root = next(b for b in arm.data.bones if b.parent is None)
    turn, head = _world_turn(arm, root), arm.matrix_world @ arm.pose.bones[root.name].head
    scene.frame_set(current)
    return turn, head


def _world_turn(arm, bone):
    """`bone`'s turn from its rest pose in Blender's world, as the scene poses it now."""
    world = arm.matrix_world
    return (world @ arm.pose.bones[bone.name].matrix).to_3x3().normalized() @ (world @ bone.matrix_local).to_3x3().normalized().inverted()


def heading(turn):
    """The angle about Blender's vertical (z) by which `turn` points the horizontal -y axis,
    radians."""
    forward = turn @ Vector((0, -1, 0))
    return atan2(forward.y, forward.x)


def _hierarchy(arm):
    """The HIERARCHY lines of the armature's rest pose and its bones in the file's order.
    An armature with several root bones, or a bone name with spaces, is refused."""
    roots = [b for b in arm.data.bones if b.parent is None]
    if len(roots) != 1:
        raise ValueError(f"{arm.name}: the armature has {len(roots)} root bones ({', '.join(b.name for b in roots[:4])}); glocal needs one")
    spaced = [b.name for b in arm.data.bones if len(b.name.split()) != 1 or b.name.split()[0] != b.name]
    if spaced:
        raise ValueError(f"{arm.name}: bone name '{spaced[0]}' has spaces, which a BVH file cannot hold; rename it")
    world = arm.matrix_world
    point = lambda v: TO_BVH @ (world @ v)
    lines, order = ["HIERARCHY"], []

    def joint(bone, depth, origin):
        order.append(bone)
        pad = "  " * depth
        head = point(bone.head_local)
        kind = "ROOT" if bone.parent is None else "JOINT"
        channels = "6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" if bone.parent is None else "3 Zrotation Xrotation Yrotation"
        lines.extend([f"{pad}{kind} {bone.name}", f"{pad}{{", f"{pad}  OFFSET {_xyz(head - origin)}", f"{pad}  CHANNELS {channels}"])
        for child in bone.children:
            joint(child, depth + 1, head)
        if not bone.children:
            tail = point(bone.tail_local)
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {_xyz(tail - head)}", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint(roots[0], 0, Vector((0, 0, 0)))
    return lines, order


def _xyz(v):
    return f"{v.x:.6f} {v.y:.6f} {v.z:.6f}"


class Take:
    """A BVH take: joint names, frame rate, and per frame each joint's world rotation (its
    turn from the rest pose, 3x3) and position, in Blender's world axes; `segments` are
    (label, first frame) pairs where glocal said them (a BVH has none of its own)."""

    def __init__(self, names, fps, rotations, positions):
        self.names, self.fps, self.rotations, self.positions = names, fps, rotations, positions
        self.segments = []

    @property
    def frames(self):
        return len(self.rotations)


def read_take(text):
    tokens = text.split()
    joints = []  # (name, parent index, offset, channels)
    stack, pos = [], 0
    while tokens[pos] != "MOTION":
        word = tokens[pos]
        if word in ("ROOT", "JOINT"):
            joints.append([tokens[pos + 1], stack[-1] if stack else None, None, []])
            stack.append(len(joints) - 1)
            pos += 2
        elif word == "End":
            stack.append(None)
            pos += 2
        elif word == "OFFSET":
            if stack[-1] is not None:
                joints[stack[-1]][2] = Vector([float(t) for t in tokens[pos + 1:pos + 4]])
            pos += 4
        elif word == "CHANNELS":
            count = int(tokens[pos + 1])
            joints[stack[-1]][3] = tokens[pos + 2:pos + 2 + count]
            pos += 2 + count
        elif word == "}":
            stack.pop()
            pos += 1
        else:
            pos += 1
    frames = int(tokens[pos + 2])
    fps = 1.0 / float(tokens[pos + 5])
    values = [float(t) for t in tokens[pos + 6:]]
    width = sum(len(j[3]) for j in joints)
    if len(values) < frames * width:
        raise ValueError(f"the take has {len(values)} numbers for {frames} frames of {width} channels")
    rotations, positions = [], []
    for f in range(frames):
        row = iter(values[f * width:(f + 1) * width])
        rots, points = [], []
        for name, parent, offset, channels in joints:
            local, turn = Vector(offset), Matrix.Identity(3)
            for channel in channels:
                v = next(row)
                axis = channel[0].upper()
                if channel.endswith("rotation"):
                    turn = turn @ Matrix.Rotation(radians(v), 3, AXES[axis])
                else:
                    local["XYZ".index(axis)] = v
            if parent is None:
                rots.append(turn)
                points.append(local)
            else:
                rots.append(rots[parent] @ turn)
                points.append(points[parent] + rots[parent] @ local)
        rotations.append([FROM_BVH @ r @ TO_BVH for r in rots])
        positions.append([FROM_BVH @ p for p in points])
    return Take([j[0] for j in joints], fps, rotations, positions)
