"""Replays: a Meshcat recording saved as one self-contained HTML file, and that
file rendered to a PNG by headless Chromium.

Typical use, around a diagram that has a MeshcatVisualizer on `meshcat`:

    meshcat = make_meshcat()
    ... MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat) ...
    meshcat.StartRecording()
    simulator.AdvanceTo(t_end)
    draw_path(meshcat, "/replay/flight", p_WO)      # optional annotations
    views = [framing_view("flight", p_WO, direction_W)]
    save_html(meshcat, "episode.html", views=views, caption="caught")
    render_html_to_png("episode.html", "episode.png")

The page opens at the first view (Meshcat's camera commands, kept in the
static HTML). A caption, a button per named view and, when asked, slow-motion
buttons sit in an overlay in the page's bottom left corner (Meshcat has no text
primitive, and the static HTML keeps none of Meshcat's controls). The page's
address may name a view and a time to open at, paused:
`episode.html#view=catch&t=1.49`.
"""

import dataclasses as dc
import html
import json
import os
import signal
import subprocess
import tempfile
import time

import numpy as np
from pydrake.geometry import Meshcat, MeshcatParams, Rgba, Sphere
from pydrake.math import RigidTransform

from regrasp_drake import atomic_io

# Debian's package `chromium` (apt-get install -y chromium).
CHROMIUM = "/usr/bin/chromium"


class ReplayError(RuntimeError):
    """Meshcat or Chromium is unavailable or failed; the message says why."""


def make_meshcat() -> Meshcat:
    """Returns a Meshcat server listening on loopback only, on a free port."""
    try:
        return Meshcat(MeshcatParams(host="localhost", port=0))
    except RuntimeError as e:
        if "DRAKE_ALLOW_NETWORK" in str(e):
            raise ReplayError(
                "Meshcat is disabled by DRAKE_ALLOW_NETWORK="
                f"{os.environ.get('DRAKE_ALLOW_NETWORK', '')!r}; "
                "unset it or add 'meshcat' to it to record a replay"
            ) from None
        raise


# Meshcat's default camera (meshcat.js): a perspective camera of this
# vertical field of view, [deg].
MESHCAT_FOV_DEG = 75.0


@dc.dataclass(frozen=True)
class View:
    """A named camera: at p_WC, looking at p_WT, [m] in Drake's z-up world
    frame, its up vector as near +Wz as can be (Meshcat.SetCameraPose)."""

    name: str
    p_WC: tuple
    p_WT: tuple


def framing_view(
    name: str,
    p_W,
    direction_W,
    aspect: float = 4 / 3,
    margin: float = 1.1,
    fov_deg: float = MESHCAT_FOV_DEG,
) -> View:
    """The nearest view from direction_W (from the scene toward the camera,
    any length) of Meshcat's default perspective camera in which every point
    of p_W (3×n, [m]) lies inside a frame of width/height ratio `aspect` (or
    any wider one), with the field of view `margin` times the points'
    extent, and the points midway between the other pair of sides. It
    looks at the points' mean depth."""
    p_W = np.asarray(p_W, float).reshape(3, -1)
    forward = -np.asarray(direction_W, float) / np.linalg.norm(direction_W)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tan_v = np.tan(np.radians(fov_deg) / 2) / margin
    tan_h = tan_v * aspect

    # The camera p_WC = a·forward + b·up + c·right sees p inside each side
    # of the frame when (p - p_WC)·(tan·forward ∓ side) >= 0: linear in
    # p_WC. The nearest camera makes the sides of one pair (top and bottom,
    # or left and right) touch a point each; the other pair is centred.
    def bound(side, tan):
        return np.min(p_W.T @ (tan * forward - side))
    top, bottom = bound(up, tan_v), bound(-up, tan_v)
    right_side, left = bound(right, tan_h), bound(-right, tan_h)
    a = min((top + bottom) / (2 * tan_v), (right_side + left) / (2 * tan_h))
    p_WC = a * forward + (bottom - top) / 2 * up + (left - right_side) / 2 * right
    depth = np.mean(p_W.T @ forward) - p_WC @ forward
    p_WT = p_WC + depth * forward
    return View(name, tuple(p_WC.tolist()), tuple(p_WT.tolist()))


def draw_path(
    meshcat: Meshcat,
    path: str,
    p_W,
    rgba: Rgba = Rgba(0.9, 0.4, 0.0, 1.0),
    bead_every: int = 8,
    bead_radius_m: float = 0.006,
):
    """Draws the points p_W (3×n, [m]) at `path` as a line through them,
    with a bead on every `bead_every`-th point (WebGL draws lines one pixel
    wide: the beads make the path visible, and their spacing shows the
    speed)."""
    p_W = np.asarray(p_W, float).reshape(3, -1)
    meshcat.SetLine(f"{path}/line", p_W, 2.0, rgba)
    for k in range(0, p_W.shape[1], bead_every):
        meshcat.SetObject(f"{path}/bead_{k}", Sphere(bead_radius_m), rgba)
        meshcat.SetTransform(f"{path}/bead_{k}", RigidTransform(p_W[:, k]))


def save_html(meshcat: Meshcat, path, **page) -> str:
    """Stops the meshcat's recording, publishes it as its animation, and writes
    the scene with that animation to path as one self-contained HTML file (the
    JavaScript is inline: it opens offline); `page` as `write_html`'s. Returns
    the path."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    return write_html(meshcat, path, **page)


def write_html(
    meshcat: Meshcat,
    path,
    *,
    views: list[View] = (),
    caption: str | None = None,
    slow_motion_from_s: float | None = None,
    slow_motion_scale: float = 0.25,
) -> str:
    """Writes meshcat's scene and animation to path (Meshcat.StaticHtml),
    opening at the first of `views` (if any), with an overlay that shows
    `caption` and a button for each view; with slow_motion_from_s, [s] of
    animation time, a button that plays the animation from there at
    slow_motion_scale times real time, and one that plays it all again at
    real time (the page opens playing at real time). Returns the path."""
    if views:
        meshcat.SetCameraPose(views[0].p_WC, views[0].p_WT)
    page = meshcat.StaticHtml()
    end = page.rfind("</body>")
    if end < 0:
        raise ReplayError("Meshcat's static HTML has no </body> to add to")
    overlay = _overlay(views, caption, slow_motion_from_s, slow_motion_scale)
    path = os.fspath(path)
    atomic_io.write_text(path, page[:end] + overlay + page[end:])
    return path


def _overlay(views, caption, slow_motion_from_s, slow_motion_scale) -> str:
    """The page's overlay: HTML with the caption and buttons, and the script
    behind them (see the module's docstring)."""
    buttons = [(f"{v.name} view", f"the camera of the {v.name} view",
                f"regrasp.view({json.dumps(v.name)})") for v in views]
    if slow_motion_from_s is not None:
        buttons += [
            (f"slow ×{slow_motion_scale:g}",
             f"plays from {slow_motion_from_s:.2f} s at {slow_motion_scale:g}"
             " times real time",
             f"regrasp.play({slow_motion_from_s}, {slow_motion_scale})"),
            ("real time", "plays from the start at real time",
             "regrasp.play(0, 1)")]
    # Drake's z-up world to three.js's y-up one: (x, y, z) -> (x, z, -y).
    cameras = {v.name: {"position": [v.p_WC[0], v.p_WC[2], -v.p_WC[1]],
                        "target": [v.p_WT[0], v.p_WT[2], -v.p_WT[1]]}
               for v in views}
    parts = ['<div id="regrasp-overlay" style="position: fixed; bottom: 8px; '
             'left: 8px; padding: 4px 8px; font: 14px sans-serif; '
             'background: rgba(255, 255, 255, 0.8); border-radius: 4px">']
    if caption:
        parts.append(f'<div style="font-weight: bold">{html.escape(caption)}</div>')
    parts += [f'<button title="{html.escape(tip)}" onclick="{html.escape(call)}">'
              f'{html.escape(label)}</button>' for label, tip, call in buttons]
    parts.append("</div>")
    script = _OVERLAY_SCRIPT.replace(
        "CAMERAS", json.dumps(cameras).replace("</", "<\\/"))
    return "\n".join(parts) + f"\n<script>{script}</script>\n"


# Drives meshcat.js's viewer (the page's `viewer`) with the commands Drake
# sends it (set_property, set_target) and its animator (seek, play, the
# mixer's timeScale: the "Animations" controls of a live Meshcat).
_OVERLAY_SCRIPT = """
var regrasp = {
  cameras: CAMERAS,
  view: function(name) {
    var camera = regrasp.cameras[name];
    viewer.handle_command({type: "set_property", property: "position",
        path: "/Cameras/default/rotated/<object>", value: camera.position});
    viewer.handle_command({type: "set_target", value: camera.target});
  },
  play: function(start_s, scale) {
    viewer.animator.mixer.timeScale = scale;
    viewer.animator.seek(start_s);
    viewer.animator.play();
  },
  // Once the animation has loaded: the view and time the address names.
  open: function() {
    if (!(viewer.animator.duration > 0)) {
      return setTimeout(regrasp.open, 50);
    }
    var asked = new URLSearchParams(location.hash.slice(1));
    if (asked.has("view")) regrasp.view(asked.get("view"));
    if (asked.has("t")) {
      viewer.animator.pause();
      viewer.animator.seek(parseFloat(asked.get("t")));
    }
  },
};
regrasp.open();
"""


def chromium_command(
    url: str, png_path: str, user_data_dir: str, window_size, budget_ms
):
    """Returns the argument list for a headless Chromium screenshot of url,
    with WebGL drawn in software (SwiftShader) and no network besides the page."""
    width, height = window_size
    return [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        f"--user-data-dir={user_data_dir}",
        f"--window-size={width},{height}",
        *([f"--virtual-time-budget={budget_ms}"] if budget_ms else []),
        f"--screenshot={png_path}",
        url,
    ]


def render_html_to_png(
    html_path,
    png_path,
    timeout_s: float = 45.0,
    window_size: tuple[int, int] = (800, 600),
    virtual_time_budget_ms: int = 3000,
    attempts: int = 3,
    fragment: str = "",
) -> str:
    """Opens html_path in headless Chromium and writes a screenshot to
    png_path, after `virtual_time_budget_ms` of page time (so that the
    animation has advanced). `fragment`, if any, is the address's part after
    "#" (a replay's view and time, e.g. "view=catch&t=1.49"). Returns
    png_path.

    Headless Chromium with a virtual time budget now and then never finishes
    (none in 25 renders here; twice in a row on one CI machine): a render that
    takes longer than timeout_s (s) is ended and tried again, up to `attempts`
    times in all, and the last attempt, if more than one, goes without a virtual
    time budget (the scene as loaded, which has drawn by the time Chromium
    takes the screenshot). Raises ReplayError if Chromium is missing, fails,
    or times out every time."""
    if not os.access(CHROMIUM, os.X_OK):
        raise ReplayError(
            f"Chromium not found at {CHROMIUM}: "
            "install it with 'apt-get install -y chromium'"
        )
    html_path = os.path.abspath(os.fspath(html_path))
    png_path = os.path.abspath(os.fspath(png_path))
    if not os.path.isfile(html_path):
        raise ReplayError(f"{html_path}: no such HTML file")
    for attempt in range(attempts):
        if os.path.exists(png_path):
            os.remove(png_path)
        last = attempt == attempts - 1 and attempts > 1
        returncode, elapsed, last_line = _run_chromium(
            "file://" + html_path + (f"#{fragment}" if fragment else ""),
            png_path,
            window_size,
            0 if last else virtual_time_budget_ms,
            timeout_s,
        )
        if returncode is not None:
            break
    if returncode is None:
        raise ReplayError(
            f"Chromium took more than {timeout_s} s to render {html_path}, "
            f"{attempts} times (last log line: {last_line})"
        )
    if returncode != 0 or not os.path.isfile(png_path):
        raise ReplayError(
            f"Chromium failed to render {html_path} "
            f"(exit {returncode}, {elapsed:.1f} s): {last_line}"
        )
    return png_path


def _run_chromium(url, png_path, window_size, budget_ms, timeout_s):
    """Runs one headless Chromium screenshot with a fresh profile. Returns
    (exit code or None on timeout, seconds taken, last line of its log)."""
    with tempfile.TemporaryDirectory(prefix="regrasp-chromium-") as work_dir:
        command = chromium_command(
            url, png_path, os.path.join(work_dir, "profile"), window_size, budget_ms
        )
        log_path = os.path.join(work_dir, "chromium.log")
        start = time.monotonic()
        # Chromium's helper processes may outlive the browser: run it in a
        # session of its own, log to a file rather than a pipe that they could
        # hold open, and end the whole session afterwards.
        with open(log_path, "w") as log:
            process = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
            try:
                returncode = process.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                returncode = None
            finally:
                _kill_session(process)
        elapsed = time.monotonic() - start
        with open(log_path, errors="replace") as log:
            lines = log.read().strip().splitlines()
    return returncode, elapsed, (lines[-1] if lines else "no output")


def _kill_session(process: subprocess.Popen):
    """Ends every process left in the session that `process` leads."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.wait()
