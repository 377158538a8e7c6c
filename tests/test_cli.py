"""The command line, as a user runs it: exit codes and one-line errors."""

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path
from unittest import mock

EXAMPLE_OBJECTS = Path(__file__).parents[1] / "examples" / "my_object.yaml"


def _object_file(directory, piece: str, name: str = "x") -> Path:
    """A one-object file in `directory`: one grasp piece (YAML flow mapping
    without the braces)."""
    path = Path(directory) / f"{name}.yaml"
    path.write_text(f"geometries:\n  g:\n    pieces:\n      - {{{piece}, "
                    "center: [0, 0, 0], grasp: true}\nobjects:\n  - {name: "
                    f"{name}, set: holdout, geometry: g, density: 200, h_cm: 0, "
                    "r_cm: 0}\n")
    return path


def _run(*args):
    return subprocess.run([sys.executable, "-m", "regrasp_drake.cli", *args],
                          capture_output=True, text=True, timeout=120)


class TestCli(unittest.TestCase):
    def test_objects_lists_catalogue(self):
        result = _run("objects", "--json")
        self.assertEqual(result.returncode, 0, result.stderr)
        rows = json.loads(result.stdout)
        sets = [r["set"] for r in rows]
        self.assertEqual(sets.count("train"), 48)
        self.assertEqual(sets.count("ablation"), 8)
        self.assertEqual(sets.count("test"), 5)
        self.assertEqual({r["name"] for r in rows if r["set"] == "test"},
                         {f"table1-row{i}" for i in range(1, 6)})

    def test_catch_refuses_out_of_range_parameters(self):
        for flag, value in (("--h-catch", "0.5"), ("--h-down", "0.02")):
            args = {"--h-catch": "0.2", "--h-down": "-0.05"} | {flag: value}
            result = _run("catch", "--object", "table1-row2",
                          *[x for kv in args.items() for x in kv])
            with self.subTest(flag=flag):
                self.assertEqual(result.returncode, 2)
                self.assertEqual(len(result.stderr.strip().splitlines()), 1)
                self.assertIn(f"{flag}: got {value}, expected", result.stderr)

    def test_bad_object_file_refused(self):
        with tempfile.TemporaryDirectory() as d:
            path = _object_file(
                d, "shape: cone, radius: 0.03, length: 0.1, axis: y")
            result = _run("objects", "--object-file", str(path))
        self.assertEqual(result.returncode, 2)
        self.assertIn("shape", result.stderr)
        self.assertEqual(len(result.stderr.strip().splitlines()), 1)

    def test_bad_scenario_refused(self):
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "s.yaml"
            path.write_text("sensors:\n  levels: 0\n")
            result = _run("catch", "--object", "table1-row2", "--h-catch", "0.2",
                          "--h-down", "-0.05", "--scenario", str(path))
        self.assertEqual(result.returncode, 2)
        self.assertIn("sensors.levels", result.stderr)

    def test_every_command_of_a_scenario_takes_its_name_and_text(self):
        from regrasp_drake import cli
        commands = {name: sub for action in cli.make_parser()._actions
                    if isinstance(action, cli.argparse._SubParsersAction)
                    for name, sub in action.choices.items()}
        with_scenario = [name for name, sub in commands.items()
                         if "--scenario" in sub._option_string_actions]
        self.assertGreaterEqual(len(with_scenario), 8)
        for name in with_scenario:
            with self.subTest(name):
                flags = commands[name]._option_string_actions
                self.assertIn("--scenario-name", flags)
                self.assertIn("--scenario-text", flags)

    def test_diagram_writes_the_catching_episodes_systems(self):
        # The Fast scenario (1 ms) with the MLP as the parameters' source:
        # the diagram holds every system of the design, wired.
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "episode.dot"
            result = _run("diagram", "--object", "table1-row2",
                          "--scenario-name", "Fast", "--scenario-text",
                          "{catch: {parameter_source: mlp}}", "--out", out)
            self.assertEqual(result.returncode, 0, result.stderr)
            text = out.read_text()
        self.assertTrue(text.startswith("digraph"))
        for system in ("name=plant", "name=arm_controller",
                       "name=catch_state_machine", "name=mlp",
                       "name=grasp_monitor", "name=infrared", "name=bumper"):
            self.assertIn(system, text)
        result = _run("diagram", "--object", "table1-row2", "--max-depth", "0")
        self.assertEqual(result.returncode, 2)
        self.assertIn("--max-depth: got 0, expected an integer >= 1",
                      result.stderr)

    def test_bad_scenario_name_or_text_refused_in_one_line(self):
        for args, expected in (
                (["--scenario-text", "{catch: {return_s: 9}}"],
                 "with --scenario-text: catch.return_s: got 9"),
                (["--scenario-name", "Nope"], "--scenario-name: got 'Nope'")):
            result = _run("catch", "--object", "table1-row2", "--h-catch",
                          "0.2", "--h-down", "-0.05", *args)
            with self.subTest(args):
                self.assertEqual(result.returncode, 2)
                self.assertEqual(len(result.stderr.strip().splitlines()), 1)
                self.assertIn(expected, result.stderr)

    def test_two_first_throw_modes_refused_together(self):
        for command in ("learn", "table1"):
            args = ["--object", "table1-row2"] if command == "learn" else []
            result = _run(command, *args, "--first-throw", "--at-release")
            with self.subTest(command=command):
                self.assertEqual(result.returncode, 2)
                self.assertEqual(len(result.stderr.strip().splitlines()), 1,
                                 result.stderr)
                self.assertIn("--at-release", result.stderr)

    def test_a_rehearsal_refused_with_the_plan_at_release(self):
        result = _run("learn", "--object", "table1-row2", "--at-release",
                      "--rehearse")
        self.assertEqual(result.returncode, 2)
        self.assertEqual(len(result.stderr.strip().splitlines()), 1,
                         result.stderr)
        self.assertIn("--rehearse: got it with --at-release", result.stderr)

    def test_too_few_throws_refused_naming_the_flag(self):
        for command, args in (("learn", ["--object", "table1-row2"]),
                              ("table1", ["--no-maps"])):
            result = _run(command, *args, "--max-throws", "1")
            with self.subTest(command=command):
                self.assertEqual(result.returncode, 2)
                self.assertEqual(len(result.stderr.strip().splitlines()), 1)
                self.assertIn("--max-throws: got 1, expected an integer >= 2",
                              result.stderr)

    def test_argument_errors_are_one_line(self):
        for args, expected in (
                (("catch", "--object", "table1-row2", "--h-catch", "abc",
                  "--h-down", "0"), "argument --h-catch: invalid float value"),
                (("learn", "--object", "table1-row2", "--search", "bogus"),
                 "argument --search: invalid choice: 'bogus'"),
                (("table1", "--maps-dir", "x", "--no-maps"),
                 "argument --no-maps: not allowed with argument --maps-dir")):
            result = _run(*args)
            with self.subTest(args=args):
                self.assertEqual(result.returncode, 2)
                self.assertEqual(len(result.stderr.strip().splitlines()), 1)
                self.assertIn(expected, result.stderr)

    def test_table1_refuses_a_bad_object_before_any_throw(self):
        from regrasp_drake import cli
        err = io.StringIO()
        with tempfile.TemporaryDirectory() as d, \
                mock.patch("regrasp_drake.learning.table1.run_table1",
                           side_effect=AssertionError("a throw ran")), \
                contextlib.redirect_stderr(err):
            code = cli.main(["table1", "--objects", "table1-row1", "none-such",
                             "--no-maps", "--library", f"{d}/library.yaml"])
        self.assertEqual(code, 2)
        self.assertIn("--objects: object name: got 'none-such'", err.getvalue())

    def test_negative_seed_refused(self):
        result = _run("train", "--seed", "-1")
        self.assertEqual(result.returncode, 2)
        self.assertEqual(result.stderr.strip(),
                         "regrasp-drake train: error: --seed: got -1, "
                         "expected an integer >= 0")

    def test_object_the_hand_cannot_hold_refused_with_the_reason(self):
        # A 0.5 m wide, 2 kg disc: within an object's bounds, but it rolls
        # off the open palm it is laid on: refused before any throw.
        with tempfile.TemporaryDirectory() as d:
            path = _object_file(
                d, "shape: cylinder, radius: 0.25, length: 0.05, axis: y", "big")
            result = _run("learn", "--object-file", str(path), "--library",
                          str(Path(d) / "library.yaml"))
        self.assertEqual(result.returncode, 2)
        lines = result.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, result.stderr)
        self.assertIn("learn: error: object big: does not rest on the open "
                      "palm", lines[0])

    def test_object_beyond_the_bounds_refused_before_any_throw(self):
        # A 0.8 m long, 20 kg cylinder: no PUMA 560 throws it.
        with tempfile.TemporaryDirectory() as d:
            path = _object_file(
                d, "shape: cylinder, radius: 0.2, length: 0.8, axis: y", "big")
            result = _run("learn", "--object-file", str(path), "--library",
                          str(Path(d) / "library.yaml"))
        self.assertEqual(result.returncode, 2)
        self.assertEqual(len(result.stderr.strip().splitlines()), 1)
        self.assertIn("pieces[0].length: got 0.8, expected a number in "
                      "[0.001, 0.3] m", result.stderr)

    def test_object_missing_refused_naming_both_flags(self):
        result = _run("learn")
        self.assertEqual(result.returncode, 2)
        self.assertEqual(len(result.stderr.strip().splitlines()), 1)
        self.assertIn("--object, --object-file: got neither", result.stderr)


    def test_unwritable_output_refused_before_any_work(self):
        with tempfile.TemporaryDirectory() as d:
            missing = str(Path(d) / "no" / "such" / "dir")
            cases = (
                (["throw", "--object", "table1-row2", "--json",
                  missing + "/t.json"], "--json", "in an existing directory"),
                (["learn", "--object", "table1-row2", "--library",
                  missing + "/lib.yaml"], "--library",
                 "in an existing directory"),
                (["grid", "--object", "table1-row2", "--out", d], "--out",
                 "a file path (it is a directory)"),
            )
            for args, flag, expected in cases:
                result = _run(*args)
                with self.subTest(command=args[0]):
                    self.assertEqual(result.returncode, 2)
                    # Refused at once: no watching throw's progress line.
                    self.assertEqual(len(result.stderr.strip().splitlines()),
                                     1, result.stderr)
                    self.assertIn(f"{flag}: got ", result.stderr)
                    self.assertIn(expected, result.stderr)
            self.assertFalse(Path(d, "no").exists())

    def test_grid_and_dataset_refuse_bad_input_before_loading_torch(self):
        """torch takes seconds to load: a bad flag, scenario, object or
        existing map is refused before it is (and before any Drake
        simulation)."""
        with tempfile.TemporaryDirectory() as d:
            bad_map = Path(d) / "map.jsonl"
            bad_map.write_text("{}\n")
            Path(d, "map.jsonl.plan.json").write_text("{}\n")
            cases = (
                ["grid", "--object", "table1-row2", "--workers", "0"],
                ["grid", "--object", "table1-row2", "--scenario-text",
                 "{bogus: 1}"],
                ["grid", "--object", "nosuch"],
                ["grid", "--object", "table1-row2", "--out", str(bad_map)],
                ["dataset", "--objects", "nosuch", "--out-dir", d],
                ["dataset", "--workers", "0", "--out-dir", d],
            )
            for args in cases:
                result = subprocess.run(
                    [sys.executable, "-c",
                     "import sys; from regrasp_drake.cli import main; "
                     "rc = main(sys.argv[1:]); "
                     "print(rc, 'torch' in sys.modules)", *args],
                    capture_output=True, text=True, timeout=120)
                with self.subTest(args=args[:3]):
                    self.assertEqual(result.stdout.split(), ["2", "False"],
                                     result.stderr)
                    self.assertIn(f"regrasp-drake {args[0]}: error: ",
                                  result.stderr)

    def test_output_cut_by_the_reader_is_no_traceback(self):
        # The reader is gone before the command writes (`objects | head`
        # when head has had its lines).
        process = subprocess.Popen(
            [sys.executable, "-m", "regrasp_drake.cli", "objects"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        process.stdout.close()
        stderr = process.stderr.read()
        process.wait(timeout=120)
        process.stderr.close()
        self.assertEqual(process.returncode, 1)
        self.assertEqual(stderr, "")


class TestExampleObjects(unittest.TestCase):
    """examples/my_object.yaml, the README's own-object example."""

    def test_learn_catches_the_files_second_object_it_names(self):
        # --object with --object-file: the named object of the file. The
        # README says the example spatula is caught on the first catching
        # throw (2 throws with the watch).
        with tempfile.TemporaryDirectory() as d:
            out, library = Path(d) / "learn.json", Path(d) / "library.yaml"
            result = _run("learn", "--object-file", str(EXAMPLE_OBJECTS),
                          "--object", "spatula-d250", "--library", str(library),
                          "--max-throws", "4", "--json", str(out))
            self.assertEqual(result.returncode, 0, result.stderr)
            report = json.loads(out.read_text())
            self.assertIn("spatula-d250", library.read_text())
        self.assertEqual(report["object"], "spatula-d250")
        self.assertTrue(report["caught"])
        self.assertEqual(report["throws"], 2)
        # After the JSON, the verdict on the last throw (target: any).
        self.assertRegex(result.stdout.strip().splitlines()[-1],
                         r"^any, \+0 mm: caught \(held ")

    def test_catch_says_a_miss_last(self):
        # h_catch 0: the fingers never close; the JSON says how it ended,
        # the last line the verdict first.
        result = _run("catch", "--object", "table1-row2", "--target", "flip",
                      "--h-catch", "0", "--h-down", "0", "--scenario-name",
                      "Fast")
        self.assertEqual(result.returncode, 0, result.stderr)
        summary = json.loads(result.stdout[:result.stdout.rindex("}") + 1])
        self.assertEqual(summary["outcome"], "timeout")
        self.assertEqual(result.stdout.strip().splitlines()[-1],
                         "flip, +0 mm: missed, not held (timeout)")

    def test_every_example_object_is_valid(self):
        result = _run("objects", "--json", "--object-file", str(EXAMPLE_OBJECTS))
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertEqual([r["name"] for r in json.loads(result.stdout)],
                         ["screwdriver-d300", "spatula-d250"])


if __name__ == "__main__":
    unittest.main()


class OutputChecksTest(unittest.TestCase):
    """Outputs refused before any work, in one line, the files left as they
    were; Ctrl-C ends a command with one line and exit 130."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.d = Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def _refused(self, argv, *fragments, kept=()):
        """main(argv) exits with 2 and one line naming every fragment,
        before the command starts, the files `kept` left as they were."""
        from regrasp_drake import cli
        before = [p.read_bytes() for p in kept]
        err, parser = io.StringIO(), cli.make_parser
        with mock.patch.object(cli, "make_parser", lambda: _with_func(
                parser(), _no_work)), contextlib.redirect_stderr(err):
            code = cli.main([str(a) for a in argv])
        self.assertEqual(code, 2, err.getvalue())
        self.assertEqual(len(err.getvalue().strip().splitlines()), 1)
        for fragment in fragments:
            self.assertIn(fragment, err.getvalue())
        self.assertEqual([p.read_bytes() for p in kept], before)

    def _accepted(self, argv):
        """The outputs of argv pass every check (the command is not run)."""
        from regrasp_drake import cli, outputs
        args = cli.make_parser().parse_args([str(a) for a in argv])
        outputs.fill_defaults(args)
        outputs.check_outputs(args)
        return args

    def test_an_output_that_is_another_output_or_an_input(self):
        library = self.d / "library.yaml"
        self._refused(["learn", "--object", "table1-row2", "--library",
                       library, "--json", library], "the same path as")
        self._refused(["grid", "--object", "table1-row2", "--out",
                       self.d / "m", "--plot", self.d / "m"],
                      "--plot: got ", "the same path as the output --out")
        objects = _object_file(self.d, "shape: sphere, radius: 0.03")
        self._refused(["throw", "--object-file", objects, "--json", objects],
                      "the same path as the input --object-file", kept=[objects])

    def test_an_existing_file_that_is_not_ours(self):
        notes = self.d / "notes.txt"
        notes.write_text("my notes\n")
        self._refused(["grid", "--object", "table1-row2", "--out", notes],
                      "without notes.txt.plan.json beside it", kept=[notes])
        self._refused(["throw", "--object", "table1-row2", "--json", notes],
                      "not JSON", kept=[notes])
        self._refused(["learn", "--object", "table1-row2", "--library", notes],
                      "--library:", kept=[notes])

    def test_a_resumed_map_with_a_malformed_row_names_its_line(self):
        rows = self.d / "m.jsonl"
        rows.write_text('{"cell": [0, 0], "outcome": "caught"}\n'
                        '{"cell": [0, 1]}\n')
        (self.d / "m.jsonl.plan.json").write_text("{}\n")
        self._refused(["grid", "--object", "table1-row2", "--out", rows],
                      "line 2: not a whole row (outcome", kept=[rows])

    def test_a_plot_matplotlib_cannot_write_and_too_many_workers(self):
        self._refused(["grid", "--object", "table1-row2", "--out",
                       self.d / "m.jsonl", "--plot", self.d / "m.xyz"],
                      "--plot: got")
        # Checked by the command, before its watching throw.
        from regrasp_drake.cli import main
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = main(["grid", "--object", "table1-row2", "--out",
                         str(self.d / "m.jsonl"), "--workers", "100000"])
        self.assertEqual(code, 2)
        self.assertIn("--workers: got 100000", err.getvalue())

    def test_every_path_argument_is_an_input_or_a_checked_output(self):
        from regrasp_drake import cli, outputs
        parser = cli.make_parser()
        commands = parser._subparsers._group_actions[0].choices
        for command, sub in commands.items():
            for action in sub._actions:
                if action.type is not Path or action.dest == "out_dir":
                    continue
                with self.subTest(command=command, argument=action.dest):
                    self.assertTrue(
                        action.dest in outputs.OUTPUTS.get(command, {})
                        or action.dest in outputs.INPUTS
                        or (command, action.dest) == ("apply", "library"))

    def test_every_output_refuses_an_existing_file_not_ours(self):
        # Each output of each command, given a file of notes (or a
        # directory holding one where a directory is written).
        from regrasp_drake import outputs
        minimal = {"catch": ["--object", "table1-row2", "--h-catch", "0.2",
                             "--h-down", "-0.05"],
                   "grid": ["--object", "table1-row2"],
                   "throw": ["--object", "table1-row2"],
                   "diagram": ["--object", "table1-row2"],
                   "learn": ["--object", "table1-row2"],
                   "regrasp": ["--object", "table1-row2", "--target", "flip"],
                   "apply": ["--object", "table1-row2"]}
        refused = 0
        for command, written in outputs.OUTPUTS.items():
            for dest, holds in written.items():
                flag = "--" + dest.replace("_", "-")
                with self.subTest(command=command, output=flag), \
                        tempfile.TemporaryDirectory() as d:
                    d = Path(d)
                    notes = d / ("notes.png" if holds == "plot"
                                 else "table1-row1.jsonl" if holds == "maps"
                                 else "notes.txt")
                    notes.write_text("my notes\n")
                    target = d if holds in outputs.DIRECTORIES else notes
                    argv = [command, *minimal.get(command, []), flag, target]
                    if (command in ("learn", "regrasp", "table1")
                            and dest != "library"):
                        argv += ["--library", d / "library.yaml"]
                    self._refused(argv, f"{flag}", "expected a new",
                                  kept=[notes])
                    refused += 1
        self.assertEqual(refused, sum(map(len, outputs.OUTPUTS.values())))

    def test_table1_refuses_a_stray_file_in_its_maps_dir_at_once(self):
        # Each object's map and plot in --maps-dir are outputs as grid's
        # are; the plan beside a map too.
        maps = self.d / "maps"
        maps.mkdir()
        cases = (("table1-row1.jsonl", "not a map",
                  "--maps-dir (table1-row1's map): got ", "without"),
                 ("table1-row2.png", "not a plot",
                  "--maps-dir (table1-row2's plot): got ", "not a plot"),
                 ("table1-row5.jsonl.plan.json", "{",
                  "--maps-dir (table1-row5's map) (its plan): got ",
                  "not JSON"))
        for name, text, *fragments in cases:
            with self.subTest(name):
                stray = maps / name
                stray.write_text(text)
                self._refused(["table1", "--maps-dir", maps, "--library",
                               self.d / "library.yaml"], *fragments,
                              kept=[stray])
                stray.unlink()
        # Other objects' files (--objects) are theirs.
        (maps / "holdout-x.jsonl").write_text("not a map")
        self._refused(["table1", "--objects", "holdout-x", "--maps-dir",
                       maps], "--maps-dir (holdout-x's map)")

    def test_outputs_of_ours_are_accepted(self):
        # The shipped files, or files written as the commands write them:
        # overwritten (or resumed) without a refusal.
        from regrasp_drake.paths import MODELS_DIR
        results = MODELS_DIR / "results"
        d = self.d
        for name in ("catch_mlp.pt", "catch_mlp.json", "catch_mlp_training.png",
                     "flight_predictor.json", "flight_predictor.json.report.json"):
            (d / name).write_bytes((MODELS_DIR / name).read_bytes())
        self._accepted(["train", "--out", d / "catch_mlp.pt"])
        self._accepted(["train-flight", "--out", d / "flight_predictor.json"])
        maps = d / "maps"
        maps.mkdir()
        (maps / "table1-row1.jsonl").write_bytes(
            (results / "maps" / "table1-row1.jsonl").read_bytes())
        (maps / "table1-row1.jsonl.plan.json").write_text("{}\n")
        (maps / "table1-row1.png").write_bytes(
            (results / "maps" / "table1-row1.png").read_bytes())
        for name in ("table1.md", "table1.json", "library_table1.yaml"):
            (d / name).write_bytes((results / name).read_bytes())
        self._accepted(["table1", "--markdown", d / "table1.md", "--json",
                        d / "table1.json", "--library",
                        d / "library_table1.yaml", "--maps-dir", maps])
        (d / "replay.html").write_text(
            "<!DOCTYPE html>\n<html>\n<head>\n  <meta charset=utf-8>\n"
            "  <title>Drake MeshCat</title>\n</head>\n")
        self._accepted(["catch", "--object", "table1-row2", "--h-catch", "0.2",
                        "--h-down", "-0.05", "--html", d / "replay.html",
                        "--json", "/dev/null", "--plot", d / "maps" /
                        "table1-row1.png"])
        (d / "dataset").mkdir()
        (d / "dataset" / "provenance.json").write_text("{}\n")
        self._accepted(["dataset", "--out", d / "dataset"])

    def test_default_outputs_go_to_the_out_dir(self):
        from regrasp_drake.paths import OUT_DIR, REPO_DIR
        self.assertIn("/out/", (REPO_DIR / ".gitignore").read_text()
                      .splitlines())
        args = self._accepted(["grid", "--object", "table1-row2",
                               "--catch-point", "2"])
        self.assertEqual(args.out, OUT_DIR / "grid-table1-row2@2.jsonl")
        args = self._accepted(["table1", "--out-dir", self.d / "o"])
        self.assertEqual((args.library, args.maps_dir),
                         (self.d / "o" / "regrasp_library.yaml",
                          self.d / "o" / "table1-maps"))
        for argv, dest, name in (
                (["learn", "--object", "table1-row2"], "library",
                 "regrasp_library.yaml"),
                (["dataset"], "out", "dataset"),
                (["train"], "out", "catch_mlp.pt"),
                (["train-flight"], "out", "flight_predictor.json")):
            with self.subTest(argv[0]):
                args = self._accepted([*argv, "--out-dir", self.d / "o"])
                self.assertEqual(getattr(args, dest), self.d / "o" / name)
                self.assertEqual(args.out_dir, self.d / "o")
        # apply reads the library learn wrote there, and writes nothing
        # there; table1 --no-maps makes no maps directory.
        args = self._accepted(["apply", "--object", "table1-row2",
                               "--out-dir", self.d / "o"])
        self.assertEqual((args.library, args.out_dir),
                         (self.d / "o" / "regrasp_library.yaml", None))
        self.assertIsNone(self._accepted(["table1", "--no-maps"]).maps_dir)
        # The directory is made only once every output is checked.
        self._refused(["learn", "--object", "table1-row2", "--out-dir",
                       self.d / "new", "--plot", self.d / "p.xyz"], "--plot")
        self.assertFalse((self.d / "new").exists())
        (self.d / "notes.txt").write_text("my notes\n")
        self._refused(["learn", "--object", "table1-row2", "--out-dir",
                       self.d / "notes.txt"], "--out-dir: got",
                      "expected a directory")

    def test_ctrl_c_ends_with_one_line_and_exit_130(self):
        from regrasp_drake import cli

        def interrupted(args):
            raise KeyboardInterrupt

        parser = cli.make_parser
        with mock.patch.object(cli, "make_parser", lambda: _with_func(
                parser(), interrupted)):
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                code = cli.main(["objects"])
        self.assertEqual(code, 130)
        self.assertEqual(len(err.getvalue().strip().splitlines()), 1)
        self.assertIn("interrupted", err.getvalue())


class InterruptTest(unittest.TestCase):
    """A real Ctrl-C (SIGINT to the process group, as a terminal sends it)
    in the cheapest command that simulates: `grid` on one worker."""

    def test_ctrl_c_keeps_the_rows_written_and_a_rerun_resumes(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "m.jsonl"
            first = self._interrupted(out, rows=1)
            # The rows written before Ctrl-C are kept, whole.
            self.assertTrue(first.endswith(b"\n"))
            from regrasp_drake.grid import plan_path, read_rows
            n = len(read_rows(out))
            self.assertEqual(n, first.count(b"\n"))
            self.assertTrue(plan_path(out).exists())
            # The rerun resumes: it keeps them and adds other cells.
            second = self._interrupted(out, rows=n + 1)
            self.assertEqual(second[:len(first)], first)
            self.assertGreater(len(read_rows(out)), n)
            self.assertEqual(len(read_rows(out)), second.count(b"\n"))

    def _interrupted(self, out: Path, rows: int) -> bytes:
        """Runs `grid` into out, sends SIGINT to its process group once out
        holds `rows` rows; asserts exit 130 and one line on stderr; returns
        out's bytes."""
        process = subprocess.Popen(
            [sys.executable, "-m", "regrasp_drake.cli", "grid", "--object",
             "table1-row2", "--out", str(out), "--workers", "1"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            start_new_session=True, preexec_fn=_default_sigint)
        deadline = time.monotonic() + 180
        while not (out.exists() and out.read_bytes().count(b"\n") >= rows):
            if process.poll() is not None or time.monotonic() > deadline:
                process.kill()
                self.fail(f"no {rows} rows: {process.communicate()[1]!r}")
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGINT)
        stdout, stderr = process.communicate(timeout=120)
        self.assertEqual(process.returncode, 130, stderr)
        lines = stderr.decode().strip().splitlines()
        self.assertEqual(len(lines), 1, stderr)
        self.assertIn("grid: interrupted; what was written so far is kept",
                      lines[0])
        return out.read_bytes()


def _default_sigint():
    """SIGINT's default action, as a terminal's foreground command has it: a
    test run started in the background of a non-interactive shell (`cmd &`,
    `nohup`) inherits SIGINT ignored, and a command rightly keeps that."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _no_work(args):
    raise AssertionError(f"`{args.command}` started before its outputs were "
                         "refused")


def _with_func(parser, func):
    """The parser, every command running `func` instead."""
    for action in parser._subparsers._group_actions:
        for sub in action.choices.values():
            sub.set_defaults(func=func)
    return parser
