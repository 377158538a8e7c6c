"""Set-up shared by the tests that simulate table1-row2."""

import torch

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.world.objects import resolve_object


class Row2Fixture:
    """Mixin for a unittest.TestCase: setUpClass gives `scenario` (the
    shipped scenario at a 1 ms step: "Fast"), `obj` (table1-row2) and
    `ik`, with one torch thread (the tests fork)."""

    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.scenario = load_scenario(name="Fast")
        cls.obj = resolve_object(name="table1-row2")
        cls.ik = ArmIk()
