"""One run of `glocal generate` in the background: the selected armature written as the
retarget rig, the command, the subprocess, and its outcome as a take or one line of error."""
import json
import os
import subprocess
import tempfile
import time

from . import bvh_io

# Bones glocal's name table does not know, by rig convention. The Rigify metarig names its
# head `spine.006`; of its two neck bones the upper one is mapped, so that the head hangs
# from it directly and the lower one turns the neck towards it.
KNOWN_JOINT_MAPS = (({"spine.004", "spine.005", "spine.006"}, {"spine.005": "Neck", "spine.006": "Head"}),)


def joint_map(arm):
    """A `--joint-map` for the armature's bones where its convention needs one, else None."""
    names = {b.name for b in arm.data.bones}
    if any(n.lower().rsplit(":", 1)[-1] == "head" for n in names):
        return None
    for needed, mapping in KNOWN_JOINT_MAPS:
        if needed <= names:
            return mapping
    return None


class Run:
    """A started `glocal generate` onto `arm`; `poll()` until it returns True, then `result()`."""

    def __init__(self, binary, model, timeline, seed, arm, fps, start=None):
        """`fps`: the frame rate the take is wanted at (the scene's). `start`: the armature's
        own motion the take continues from, as a BVH text ([`bvh_io.posed_bvh`]), or None for
        the model's own start."""
        self.folder = tempfile.TemporaryDirectory(prefix="glocal-")
        rig = os.path.join(self.folder.name, "rig.bvh")
        self.take_path = os.path.join(self.folder.name, "take.bvh")
        with open(rig, "w") as f:
            f.write(bvh_io.rig_bvh(arm))
        self.command = [binary, "generate", "--model", model, "--timeline", timeline, "--seed", str(seed),
                        "--retarget-to", rig, "--out", self.take_path, "--json", "--fps", f"{fps:.6f}"]
        if start is not None:
            start_path = os.path.join(self.folder.name, "start.bvh")
            with open(start_path, "w") as f:
                f.write(start)
            self.command += ["--init", f"clip:{start_path}@0"]
        mapping = joint_map(arm)
        if mapping:
            map_path = os.path.join(self.folder.name, "joint_map.json")
            with open(map_path, "w") as f:
                json.dump(mapping, f)
            self.command += ["--joint-map", map_path]
        self.started = time.monotonic()
        self.process = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def poll(self):
        return self.process.poll() is not None

    def elapsed(self):
        return time.monotonic() - self.started

    def result(self):
        """The take read back with its segments, or raises RuntimeError with glocal's error
        as one line."""
        out, err = self.process.communicate()
        try:
            if self.process.returncode != 0:
                raise RuntimeError(error_line(err) or f"glocal exited with status {self.process.returncode}")
            with open(self.take_path) as f:
                take = bvh_io.read_take(f.read())
            take.segments = segments(out)
            return take
        finally:
            self.folder.cleanup()

    def cancel(self):
        self.process.kill()
        self.process.communicate()
        self.folder.cleanup()


def error_line(stderr):
    """glocal's `error: ...` line (the last one), else the last line it printed."""
    lines = [l.strip() for l in stderr.splitlines() if l.strip()]
    errors = [l for l in lines if l.lower().startswith("error")]
    line = (errors or lines or [""])[-1]
    return line[len("error:"):].strip() if line.lower().startswith("error:") else line


def segments(stdout):
    """(label, first frame) of each segment, from the summary `glocal generate --json` prints
    last: `walking` or `walking/tired`, frames counted from 0."""
    lines = [l for l in stdout.splitlines() if l.strip()]
    try:
        spans = json.loads(lines[-1])["segments"] if lines else []
        return [(s["name"] + (f"/{s['style']}" if s.get("style") else ""), int(s["start_frame"])) for s in spans]
    except (ValueError, KeyError, TypeError):
        # A take without markers rather than no take: the markers only name its parts.
        return []
