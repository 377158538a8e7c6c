"""Where the package's data lives: every path of it the package reads or
writes by default starts here.

Run from its checkout (an editable install, or PYTHONPATH at the
repository's top), the data is the repository's: `sdf/` and `models/` at
its top, outputs in its git-ignored `out/`. Installed from a wheel, the
robot, hand and object descriptions and the shipped models travel inside
the package (pyproject.toml maps `sdf/` to `regrasp_drake.sdf` and the
shipped part of `models/` to `regrasp_drake.models`), found through
importlib.resources, and outputs go to `./out` of the working directory.
The data sets and results stay in the repository.
"""

from importlib import resources
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
# The repository's top when the package runs from its checkout, else None.
REPO_DIR = (PACKAGE_DIR.parent
            if (PACKAGE_DIR.parent / "pyproject.toml").is_file()
            and (PACKAGE_DIR.parent / "sdf" / "package.xml").is_file()
            else None)


def _installed(name: str) -> Path:
    """A data folder installed inside the package (a wheel's files are on
    disk, so its Traversable is a path)."""
    return Path(str(resources.files("regrasp_drake") / name))


# The robot, hand and object descriptions (with the package.xml that
# resolves their package://regrasp_drake/ URLs), and the object catalogue.
SDF_DIR = REPO_DIR / "sdf" if REPO_DIR else _installed("sdf")
# The trained networks, flight model and offset prior, and the training
# maps (models/dataset/maps.npz) the map-prior search reads.
MODELS_DIR = REPO_DIR / "models" if REPO_DIR else _installed("models")
# Where a command writes the outputs it is not given a path for (its
# --out-dir overrides it): ignored by git in the checkout.
OUT_DIR = REPO_DIR / "out" if REPO_DIR else Path.cwd() / "out"
