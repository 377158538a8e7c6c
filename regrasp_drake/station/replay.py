"""Replays: a Meshcat recording saved as one self-contained HTML file, and that
file rendered to a PNG by headless Chromium.

Typical use, around a diagram that has a MeshcatVisualizer on `meshcat`:

    meshcat = make_meshcat()
    ... MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat) ...
    meshcat.StartRecording()
    simulator.AdvanceTo(t_end)
    save_html(meshcat, "episode.html")
    render_html_to_png("episode.html", "episode.png")
"""

import os
import signal
import subprocess
import tempfile
import time

from pydrake.geometry import Meshcat, MeshcatParams

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


def save_html(meshcat: Meshcat, path) -> str:
    """Stops the meshcat's recording, publishes it as its animation, and writes
    the scene with that animation to path as one self-contained HTML file (the
    JavaScript is inline: it opens offline). Returns the path."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    path = os.fspath(path)
    with open(path, "w", encoding="utf-8") as f:
        f.write(meshcat.StaticHtml())
    return path


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
) -> str:
    """Opens html_path in headless Chromium and writes a screenshot to
    png_path, after `virtual_time_budget_ms` of page time (so that the
    animation has advanced). Returns png_path.

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
            "file://" + html_path,
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
