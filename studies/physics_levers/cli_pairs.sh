#!/usr/bin/env bash
# The catch command of two trees in turn, in one run (section 6 of FINDINGS.md):
#   studies/physics_levers/cli_pairs.sh OLD_COMMIT [PAIRS]
# checks OLD_COMMIT out in a scratch worktree, then runs
#   regrasp-drake catch --object table1-row2 --h-catch 0.3 --h-down -0.07 --json F
# with it and with this tree alternately, PAIRS times (default 7), and prints
# each pair's wall_s (the catch with its throw reused, as `catch` reports it),
# the medians, the real-time factors (sim_time_s / wall_s) and the median of
# the pairwise ratios.
set -euo pipefail
old=${1:?usage: cli_pairs.sh OLD_COMMIT [PAIRS]}
pairs=${2:-7}
here=$(cd "$(dirname "$0")/../.." && pwd)
scratch=$(mktemp -d)
trap 'git -C "$here" worktree remove --force "$scratch/old" >/dev/null 2>&1; rm -rf "$scratch"' EXIT
git -C "$here" worktree add -q --detach "$scratch/old" "$old"
catch() {  # catch TREE JSON
  (cd "$1" && PYTHONPATH="$1" "$here/.venv/bin/python" -m regrasp_drake.cli catch \
     --object table1-row2 --h-catch 0.3 --h-down -0.07 --json "$2" >/dev/null)
}
for _ in $(seq "$pairs"); do
  catch "$scratch/old" "$scratch/old.json"
  catch "$here" "$scratch/new.json"
  python3 -c "import json,sys; a,b=(json.load(open(p)) for p in sys.argv[1:]); print(a['wall_s'], b['wall_s'], a['sim_time_s'], a['outcome'], b['outcome'])" \
    "$scratch/old.json" "$scratch/new.json"
done | python3 -c "
import statistics, sys
rows = [line.split() for line in sys.stdin]
for r in rows: print('pair: old', r[0], 's, new', r[1], 's;', r[3], r[4])
old, new = [float(r[0]) for r in rows], [float(r[1]) for r in rows]
sim = float(rows[0][2])
print(f'median old {statistics.median(old):.3f} s ({sim / statistics.median(old):.2f}x), '
      f'new {statistics.median(new):.3f} s ({sim / statistics.median(new):.2f}x), '
      f'pairwise new/old {statistics.median(n / o for o, n in zip(old, new)):.3f}')"
