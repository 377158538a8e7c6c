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

from regrasp_drake.station import replay
from regrasp_drake.station.replay import (
    CHROMIUM,
    ReplayError,
    make_meshcat,
    render_html_to_png,
    save_html,
)

BOX_RGBA = [0.9, 0.1, 0.1, 1.0]  # The falling box is red,
GROUND_RGBA = [0.1, 0.7, 0.1, 1.0]  # the ground green.
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
