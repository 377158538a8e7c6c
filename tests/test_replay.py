import base64
import html
import math
import os
import re
import tempfile
import time
import unittest
from unittest import mock

import matplotlib.image
import numpy as np
from pydrake.geometry import Box, MeshcatVisualizer
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.multibody.tree import SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.episode import replay
from regrasp_drake.episode.replay import (
    CHROMIUM,
    MESHCAT_FOV_DEG,
    ReplayError,
    View,
    framing_view,
    make_meshcat,
    render_html_to_png,
    save_html,
    write_html,
)
from regrasp_drake.learning.run_replay import unpack
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import catch_once, episode_caption, save_replay
from regrasp_drake.world.objects import load_catalogue

BOX_RGBA = [0.9, 0.1, 0.1, 1.0]  # The falling box is red,
GROUND_RGBA = [0.1, 0.7, 0.1, 1.0]  # the ground green.
# Meshcat's opening camera position in the static HTML (three.js's y-up
# frame), which a replay's own camera replaces.
DEFAULT_CAMERA = [0.0, 1.0, 3.0]
HAVE_CHROMIUM = os.access(CHROMIUM, os.X_OK)
if not HAVE_CHROMIUM:
    print(
        f"test_replay: {CHROMIUM} is absent (apt-get install -y chromium): "
        "rendering skipped"
    )


def _record_falling_box(meshcat, duration_s=0.5):
    """Simulates a 0.2 m box dropped from 0.5 m onto a ground slab for
    duration_s while meshcat records it."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    friction = CoulombFriction(0.5, 0.5)
    box = plant.AddRigidBody(
        "box", SpatialInertia(1.0, np.zeros(3), UnitInertia.SolidBox(0.2, 0.2, 0.2))
    )
    plant.RegisterVisualGeometry(
        box, RigidTransform(), Box(0.2, 0.2, 0.2), "box", BOX_RGBA
    )
    plant.RegisterCollisionGeometry(
        box, RigidTransform(), Box(0.2, 0.2, 0.2), "box", friction
    )
    X_WG = RigidTransform([0.0, 0.0, -0.05])
    ground = plant.world_body()
    plant.RegisterVisualGeometry(
        ground, X_WG, Box(1.0, 1.0, 0.1), "ground", GROUND_RGBA
    )
    plant.RegisterCollisionGeometry(
        ground, X_WG, Box(1.0, 1.0, 0.1), "ground", friction
    )
    plant.Finalize()
    MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant.SetFreeBodyPose(
        plant.GetMyMutableContextFromRoot(context), box, RigidTransform([0, 0, 0.5])
    )
    simulator = Simulator(diagram, context)
    meshcat.StartRecording()
    simulator.AdvanceTo(duration_s)


def _commands(page: str) -> list:
    """The Meshcat commands of a static HTML page, decoded; those that
    run_replay.unpack cannot decode (meshes' typed arrays) left out."""
    commands = []
    for data in re.findall(
            r'fetch\("data:application/octet-binary;base64,([^"]*)"\)', page):
        try:
            commands.append(unpack(base64.b64decode(data)))
        except ValueError:
            pass
    return commands


def _camera_position(page: str):
    """The camera position the page's scene sets, three.js frame, [m]."""
    found = [c["value"] for c in _commands(page)
             if c.get("type") == "set_property"
             and c.get("path") == "/Cameras/default/rotated/<object>"
             and c.get("property") == "position"]
    return found[-1] if found else DEFAULT_CAMERA


class FramingViewTest(unittest.TestCase):
    def test_points_fill_the_frame(self):
        rng = np.random.default_rng(46)
        p_W = rng.normal(size=(3, 200)) * [[0.2], [0.1], [0.5]] + [[1], [0], [1]]
        for direction_W in [(1, 0, 0), (0.84, 0.48, 0.26), (-1, 2, -0.5)]:
            view = framing_view("v", p_W, direction_W, aspect=4 / 3, margin=1.1)
            p_WC, p_WT = np.array(view.p_WC), np.array(view.p_WT)
            forward = (p_WT - p_WC) / np.linalg.norm(p_WT - p_WC)
            np.testing.assert_allclose(
                -forward, np.array(direction_W) / np.linalg.norm(direction_W))
            right = np.cross(forward, [0, 0, 1])
            right /= np.linalg.norm(right)
            up = np.cross(right, forward)
            rel = p_W.T - p_WC
            depth = rel @ forward
            self.assertTrue(np.all(depth > 0))
            # Tangents of the points' angles off the axis, over the frame's.
            tan_v = math.tan(math.radians(MESHCAT_FOV_DEG) / 2)
            v = (rel @ up) / depth / tan_v
            h = (rel @ right) / depth / (tan_v * 4 / 3)
            # Inside, and one pair of opposite sides touched at 1/margin.
            self.assertLessEqual(max(np.abs(v).max(), np.abs(h).max()),
                                 1 / 1.1 + 1e-9)
            touched = [a for a in (v, h) if np.isclose(a.max(), 1 / 1.1)]
            self.assertEqual(len(touched), 1)
            self.assertAlmostEqual(touched[0].min(), -1 / 1.1)


class ReplayTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        cls.meshcat = make_meshcat()
        _record_falling_box(cls.meshcat)
        cls.html_size_without_animation = len(cls.meshcat.StaticHtml())
        cls.html_path = save_html(
            cls.meshcat, os.path.join(cls.dir.name, "replay.html")
        )

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    def test_meshcat_listens_on_loopback(self):
        self.assertRegex(
            self.meshcat.web_url(), r"^http://(localhost|127\.0\.0\.1):\d+$"
        )

    def test_html_holds_the_animation(self):
        # save_html published the recording: 0.5 s at the visualizer's 64 Hz
        # adds about 33 frames of the box's pose to the file.
        added = os.path.getsize(self.html_path) - self.html_size_without_animation
        self.assertGreater(added, 33 * 50)
        self.assertEqual(self.meshcat.get_mutable_recording().frames_per_second(), 64)

    def test_html_is_self_contained(self):
        with open(self.html_path, encoding="utf-8") as f:
            html = f.read()
        self.assertGreater(len(html), 100_000)  # The viewer's JavaScript is inline.
        external = re.findall(
            r"<(?:script|link|img)[^>]*(?:src|href)\s*=\s*[\"']?(?:https?:)?//",
            html,
            re.I,
        )
        self.assertEqual(external, [])
        self.assertIn("<script", html)

    def test_page_opens_at_the_first_view_with_the_caption(self):
        view = View("side", (2.0, -1.0, 0.5), (0.0, 0.0, 0.25))
        path = write_html(
            self.meshcat, os.path.join(self.dir.name, "views.html"),
            views=[view, View("top", (0.0, 0.0, 3.0), (0.1, 0.0, 0.0))],
            caption="box <dropped> & caught", slow_motion_from_s=0.25)
        with open(path, encoding="utf-8") as f:
            page = f.read()
        # Drake's (x, y, z) is three.js's (x, z, -y).
        self.assertEqual(_camera_position(page), [2.0, 0.5, 1.0])
        targets = [c["value"] for c in _commands(page)
                   if c.get("type") == "set_target"]
        self.assertEqual(targets, [[0.0, 0.25, -0.0]])
        self.assertIn(html.escape("box <dropped> & caught"), page)
        self.assertNotIn("box <dropped>", page)
        for label in ("side view", "top view", "slow ×0.25", "real time"):
            self.assertIn(f">{label}</button>", page)
        # The overlay comes after the scene's script, inside the body.
        self.assertLess(page.index("embedded-json"), page.index("regrasp-overlay"))
        self.assertTrue(page.rstrip().endswith("</html>"))

    @unittest.skipUnless(
        HAVE_CHROMIUM, f"{CHROMIUM} is absent (apt-get install -y chromium)"
    )
    def test_render_draws_the_scene(self):
        png_path = render_html_to_png(
            self.html_path, os.path.join(self.dir.name, "replay.png"), timeout_s=45
        )
        rgb = matplotlib.image.imread(png_path)[..., :3]
        self.assertEqual(rgb.shape, (600, 800, 3))
        colours = np.unique((rgb * 255).astype(np.uint8).reshape(-1, 3), axis=0)
        self.assertGreater(len(colours), 50)  # Shading, not a blank page.
        r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
        red = np.count_nonzero((r > 0.5) & (g < 0.3) & (b < 0.3))
        green = np.count_nonzero((g > 0.4) & (r < 0.4) & (b < 0.4))
        self.assertGreater(red, 50, "the box is not drawn")
        self.assertGreater(green, 500, "the ground is not drawn")

    @unittest.skipUnless(
        HAVE_CHROMIUM, f"{CHROMIUM} is absent (apt-get install -y chromium)"
    )
    def test_empty_page_renders_blank(self):
        # The same render of a page without a scene has none of those colours.
        empty = os.path.join(self.dir.name, "empty.html")
        with open(empty, "w") as f:
            f.write("<html><body></body></html>")
        rgb = matplotlib.image.imread(
            render_html_to_png(
                empty,
                os.path.join(self.dir.name, "empty.png"),
                virtual_time_budget_ms=100,
            )
        )[..., :3]
        self.assertEqual(len(np.unique(rgb.reshape(-1, 3), axis=0)), 1)


@unittest.skipUnless(
    HAVE_CHROMIUM, f"{CHROMIUM} is absent (apt-get install -y chromium)"
)
class CatchReplayTest(unittest.TestCase):
    """The replay `regrasp-drake catch --html` and the main command write
    (throw_catch.save_replay), of table1-row2 caught in the Fast scenario,
    rendered at the grasp's time: with the robot, and written again with the
    arm and hand hidden (the same page otherwise: scene, camera, overlay).
    The pixels that differ are the robot's."""

    PATHS = ("/drake/visualizer/puma560", "/drake/visualizer/hand")

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        scenario = load_scenario(name="Fast")
        meshcat = make_meshcat()
        cls.result, plan = catch_once(
            scenario, load_catalogue()["table1-row2"], h_catch=0.32,
            h_down=-0.07, meshcat=meshcat)
        def save(name):
            return save_replay(
                meshcat, os.path.join(cls.dir.name, name), cls.result, plan,
                ArmIk(scenario.directives),
                caption=episode_caption(cls.result))
        cls.html = save("catch.html")
        for path in cls.PATHS:
            meshcat.SetProperty(path, "visible", False)
        cls.hidden_html = save("hidden.html")
        cls.at = f"t={cls.result.catch_time_s}"
        cls.rgb = cls._render(cls.html, cls.at)
        cls.hidden_rgb = cls._render(cls.hidden_html, cls.at)

    @classmethod
    def _render(cls, html_path, fragment):
        png = os.path.join(cls.dir.name, f"{len(os.listdir(cls.dir.name))}.png")
        return matplotlib.image.imread(
            render_html_to_png(html_path, png, fragment=fragment))[..., :3]

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    def test_caught_and_captioned(self):
        self.assertEqual(self.result.outcome, "caught", self.result.message)
        with open(self.html, encoding="utf-8") as f:
            page = f.read()
        self.assertIn("table1-row2: caught at", page)

    def test_camera_is_not_the_default(self):
        with open(self.html, encoding="utf-8") as f:
            position = _camera_position(f.read())
        self.assertGreater(
            np.linalg.norm(np.subtract(position, DEFAULT_CAMERA)), 0.5)

    def test_robot_spans_half_the_frame_height(self):
        robot = np.any(np.abs(self.rgb - self.hidden_rgb) > 0.1, axis=2)
        height, width = robot.shape
        self.assertLess(robot.mean(), 0.6, "more than the robot changed")
        rows = np.flatnonzero(robot.any(axis=1))
        self.assertGreater(rows.size, 0, "the robot is not drawn")
        share = (rows[-1] - rows[0] + 1) / height
        print(f"CatchReplayTest: the robot's bounding box spans {share:.0%} "
              f"of the frame's height, its pixels {robot.mean():.0%} of it")
        self.assertGreaterEqual(share, 0.5)

    def test_catch_view_moves_the_camera(self):
        catch = self._render(self.html, f"view=catch&{self.at}")
        changed = np.any(np.abs(catch - self.rgb) > 0.1, axis=2).mean()
        self.assertGreater(changed, 0.2)


def _is_running(pid, grace_s=2.0):
    """True if process pid still exists, and is not a zombie, after grace_s (s)
    for a kill to take effect."""
    deadline = time.monotonic() + grace_s
    while True:
        try:
            with open(f"/proc/{pid}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return False
        if state == "Z":
            return False
        if time.monotonic() > deadline:
            return True
        time.sleep(0.05)


class ReplayErrorsTest(unittest.TestCase):
    def test_missing_chromium_is_a_clear_error(self):
        with mock.patch.object(replay, "CHROMIUM", "/nonexistent/chromium"):
            with self.assertRaisesRegex(ReplayError, "apt-get install -y chromium"):
                render_html_to_png("x.html", "x.png")

    def test_hanging_chromium_is_ended_and_retried(self):
        with tempfile.TemporaryDirectory() as d:
            # A stand-in for Chromium that never finishes, with a helper child.
            fake = os.path.join(d, "chromium")
            with open(fake, "w") as f:
                f.write(f"#!/bin/sh\necho \"$@\" >> {d}/args\n"
                        f"sleep 60 &\necho $! >> {d}/pids\nsleep 60\n")
            os.chmod(fake, 0o755)
            html = os.path.join(d, "page.html")
            open(html, "w").close()
            with mock.patch.object(replay, "CHROMIUM", fake):
                with self.assertRaisesRegex(ReplayError, "more than 0.5 s.*3 times"):
                    render_html_to_png(html, os.path.join(d, "x.png"), timeout_s=0.5)
            with open(os.path.join(d, "pids")) as f:
                helpers = [int(line) for line in f]
            with open(os.path.join(d, "args")) as f:
                budgets = ["--virtual-time-budget=3000" in line for line in f]
        self.assertEqual(len(helpers), 3)  # Three attempts,
        for pid in helpers:  # each with its helper ended too.
            self.assertFalse(_is_running(pid), pid)
        # The last without the virtual time budget that can hang Chromium.
        self.assertEqual(budgets, [True, True, False])

    def test_meshcat_disabled_by_environment(self):
        with mock.patch.dict(os.environ, {"DRAKE_ALLOW_NETWORK": "none"}):
            with self.assertRaisesRegex(ReplayError, "DRAKE_ALLOW_NETWORK"):
                make_meshcat()


if __name__ == "__main__":
    unittest.main()
