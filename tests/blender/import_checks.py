"""What the Blender import checks share: the skeleton against the JSON export's joints and
parents, the imported action's frame count, printing the failures, and the command line
(pairs of an exported file and the same take exported as JSON). The scripts run with their
own folder on the module path, so `import import_checks` finds this file.
"""
import os
import sys

SETUP = """Blender as a Python module (not part of `cargo test`; about 400 MB):
    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy
Exits non-zero when any check fails."""


def skeleton_failures(bones, take):
    """The armature's bones against the take's joint names and parents."""
    names, parents = take["joints"], take["parents"]
    failures = []
    if sorted(b.name for b in bones) != sorted(names):
        failures.append(f"bones {sorted(b.name for b in bones)} != joints {sorted(names)}")
    for name, parent in zip(names, parents):
        bone = bones.get(name)
        want = None if parent is None or parent < 0 else names[parent]
        got = bone.parent.name if bone and bone.parent else None
        if bone and got != want:
            failures.append(f"{name}: parent {got}, expected {want}")
    return failures


def imported_frames(arm, take, failures):
    """The first frame of the armature's action and its frame count, checked against the take's."""
    first, last = arm.animation_data.action.frame_range
    frames = int(round(last - first)) + 1
    if frames != len(take["frames"]):
        failures.append(f"{frames} frames in Blender, {len(take['frames'])} exported")
    return int(first), frames


def passed(failures):
    for f in failures:
        print("  FAIL:", f)
    return not failures


def main(check, usage):
    """Runs `check(exported, json)` on every pair of arguments; exits non-zero when any fails."""
    args = sys.argv[1:]
    if len(args) < 2 or len(args) % 2:
        sys.exit(f"{usage}\n{SETUP}")
    ok = all([check(args[i], args[i + 1]) for i in range(0, len(args), 2)])
    # bpy 4.2 as a module crashes in its own teardown after a glTF import (exit 139 with
    # every check passed): leave without it once the report is out.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0 if ok else 1)
