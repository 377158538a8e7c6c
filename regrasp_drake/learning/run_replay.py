"""One Meshcat replay of every throw of a run (the learning phase's watching
throw and catch attempts), one after the other, in one HTML file.

Every episode records on the same Meshcat, but `Meshcat.StartRecording`
(called by `run_episode`) starts a new, empty animation each time in pydrake
1.51: a shared Meshcat alone would keep the last throw only. So after each
episode, its published animation (the `set_animation` command of
`Meshcat.StaticHtml()`, MessagePack) is read back and copied into one
combined MeshcatAnimation, shifted to start after the previous throws; `save`
publishes the combined animation and writes the page. The scene's geometry is
the same in every episode of one object.

Typical use:

    replay = RunReplay()
    result = run_episode(..., meshcat=replay.meshcat)
    replay.add_episode(result.sim_time_s)
    ...
    replay.save("run.html")
"""

import base64
import math
import re
import struct

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.geometry import MeshcatAnimation
from pydrake.math import RigidTransform

from regrasp_drake.episode.replay import make_meshcat, write_html


class RunReplay:
    """A Meshcat for every episode of a run, and their combined animation."""

    def __init__(self, gap_s: float = 0.5, meshcat=None):
        """gap_s: the still time between two throws, [s]; meshcat: where
        the episodes are drawn and recorded, e.g. Drake's StartMeshcat()
        in a notebook (default: a new one on loopback, `make_meshcat`)."""
        self.meshcat = make_meshcat() if meshcat is None else meshcat
        # An earlier run's marks (throw_catch.save_replay's) on a reused one.
        self.meshcat.Delete("/replay")
        self._gap_s = gap_s      # still time between two throws, [s]
        self._offset_s = 0.0     # where the next episode starts, [s]
        self._animation = None
        self.episodes = 0

    def add_episode(self, duration_s: float) -> None:
        """Copies the episode just recorded on `meshcat` (duration_s of
        simulated time) into the combined animation, after the previous
        ones."""
        recorded = _published_animation(self.meshcat.StaticHtml())
        if recorded is None:
            raise RuntimeError("no animation on the meshcat: was the episode "
                               "run with meshcat=replay.meshcat?")
        fps = recorded["animations"][0]["clip"]["fps"] if recorded[
            "animations"] else 64.0
        if self._animation is None:
            self._animation = MeshcatAnimation(fps)
        offset = int(math.ceil(self._offset_s * fps))
        self._offset_s += duration_s + self._gap_s
        # Hold the last poses until the frame before the next throw starts.
        hold = int(math.ceil(self._offset_s * fps)) - 1
        for track_set in recorded["animations"]:
            _copy_path(self._animation, track_set, offset, hold)
        self.episodes += 1

    def save(self, path) -> str:
        """Writes the combined animation's page to path (one self-contained
        HTML file, as `replay.save_html`). Returns path."""
        if self._animation is None:
            raise RuntimeError("no episode added to the replay")
        self.meshcat.StopRecording()
        self.meshcat.SetAnimation(self._animation)
        return write_html(self.meshcat, path)


def _copy_path(animation: MeshcatAnimation, track_set: dict, offset: int,
               hold: int) -> None:
    """Copies one path's position and quaternion tracks into `animation`,
    shifted by `offset` frames; the last pose is held until frame `hold` (so
    that nothing glides from one throw's end into the next one's start: the
    player interpolates between keys)."""
    path = track_set["path"]
    keys = {}
    for track in track_set["clip"]["tracks"]:
        name = track["name"].lstrip(".")
        if name in ("position", "quaternion"):
            keys[name] = {k["time"]: k["value"] for k in track["keys"]}
    if not keys:
        return
    frames = sorted(set().union(*(k.keys() for k in keys.values())))
    position, quaternion = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]
    for frame in frames:
        position = keys.get("position", {}).get(frame, position)
        quaternion = keys.get("quaternion", {}).get(frame, quaternion)
        animation.SetTransform(int(frame) + offset, path,
                               _transform(position, quaternion))
    if hold > frames[-1] + offset:
        animation.SetTransform(hold, path, _transform(position, quaternion))


def _transform(position, quaternion_xyzw) -> RigidTransform:
    x, y, z, w = quaternion_xyzw  # three.js order
    q = np.array([w, x, y, z], float)
    return RigidTransform(Quaternion(q / np.linalg.norm(q)), position)


_COMMAND = re.compile(r'fetch\("data:application/octet-binary;base64,([^"]*)"\)')


def _published_animation(html: str) -> dict | None:
    """The last `set_animation` command of a Meshcat page, decoded."""
    found = None
    for match in _COMMAND.finditer(html):
        message = unpack(base64.b64decode(match.group(1)))
        if isinstance(message, dict) and message.get("type") == "set_animation":
            found = message
    return found


def unpack(data: bytes):
    """Decodes one MessagePack value (the subset Meshcat writes: nil,
    booleans, integers, floats, strings, binary, extensions (as their
    bytes), arrays, maps)."""
    value, end = _unpack(memoryview(data), 0)
    if end != len(data):
        raise ValueError(f"{len(data) - end} bytes after the MessagePack value")
    return value


# Extension types: ext 8/16/32 by the width of their length, [bytes], and
# fixext by their data's length, [bytes]; decoded as their bytes.
_EXT = {0xC7: 1, 0xC8: 2, 0xC9: 4}
_FIXEXT = {0xD4: 1, 0xD5: 2, 0xD6: 4, 0xD7: 8, 0xD8: 16}
_FIXED = {0xCC: ">B", 0xCD: ">H", 0xCE: ">I", 0xCF: ">Q", 0xD0: ">b",
          0xD1: ">h", 0xD2: ">i", 0xD3: ">q", 0xCA: ">f", 0xCB: ">d"}


def _unpack(b: memoryview, i: int):
    tag = b[i]
    i += 1
    if tag <= 0x7F:
        return tag, i
    if tag >= 0xE0:
        return tag - 0x100, i
    if 0x80 <= tag <= 0x8F:
        return _map(b, i, tag & 0x0F)
    if 0x90 <= tag <= 0x9F:
        return _array(b, i, tag & 0x0F)
    if 0xA0 <= tag <= 0xBF:
        n = tag & 0x1F
        return str(b[i:i + n], "utf-8"), i + n
    if tag == 0xC0:
        return None, i
    if tag in (0xC2, 0xC3):
        return tag == 0xC3, i
    if tag in _FIXED:
        fmt = _FIXED[tag]
        return struct.unpack_from(fmt, b, i)[0], i + struct.calcsize(fmt)
    if tag in _EXT or tag in _FIXEXT:  # typed arrays (a line's points)
        n = _FIXEXT.get(tag) or int.from_bytes(b[i:i + _EXT[tag]], "big")
        i += _EXT.get(tag, 0) + 1  # the length, then the ext's type
        return bytes(b[i:i + n]), i + n
    sizes = {0xD9: (1, "s"), 0xDA: (2, "s"), 0xDB: (4, "s"),
             0xC4: (1, "b"), 0xC5: (2, "b"), 0xC6: (4, "b"),
             0xDC: (2, "a"), 0xDD: (4, "a"), 0xDE: (2, "m"), 0xDF: (4, "m")}
    if tag not in sizes:
        raise ValueError(f"MessagePack tag 0x{tag:02x} at byte {i - 1} is not "
                         f"supported")
    width, kind = sizes[tag]
    n = int.from_bytes(b[i:i + width], "big")
    i += width
    if kind == "s":
        return str(b[i:i + n], "utf-8"), i + n
    if kind == "b":
        return bytes(b[i:i + n]), i + n
    return (_array if kind == "a" else _map)(b, i, n)


def _array(b, i, n):
    items = []
    for _ in range(n):
        item, i = _unpack(b, i)
        items.append(item)
    return items, i


def _map(b, i, n):
    items = {}
    for _ in range(n):
        key, i = _unpack(b, i)
        items[key], i = _unpack(b, i)
    return items, i
