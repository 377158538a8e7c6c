"""Which end of each Table 1 object comes down first at its catch moment,
and where its centre of mass lies, in the planned palm's frame G (x across
the object's axis, y along it).

    .venv/bin/python studies/palm_toss/landing_end.py

Watches each object's throw on the shipped scenario, plans its catch, and
prints the object's angular velocity there, the vertical velocity of the
point 0.1 m along +y_G from the centre of mass relative to it (negative: the
+y end comes down first), and the centre of mass in G (mm). FINDINGS.md,
"Where the palm should wait along the axis", reads these.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object


def main() -> None:
    scenario, ik = load_scenario(), ArmIk()
    for k in range(1, 6):
        obj = resolve_object(name=f"table1-row{k}")
        watched = watch(scenario, obj, ik)
        plan = plan_catch(scenario, obj, ik, watched)
        i = int(np.argmin(abs(watched.logs.t - plan.catch_point.t_s)))
        x = watched.logs.object_state[:, i]
        R_WO = RotationMatrix(Quaternion(x[:4] / np.linalg.norm(x[:4])))
        w_W = x[7:10]
        R_WG = plan.X_WG.rotation().matrix()
        vz = np.cross(w_W, 0.1 * R_WG[:, 1])[2]
        p_GCm = R_WG.T @ (x[4:7] + R_WO.matrix() @ obj.p_OCm
                          - plan.X_WG.translation())
        print(f"{obj.name}: w_W {np.round(w_W, 2)} rad/s; +y end "
              f"{vz:+.3f} m/s ({'down' if vz < 0 else 'up'}); centre of "
              f"mass in G {np.round(1000 * p_GCm, 1)} mm")


if __name__ == "__main__":
    main()
