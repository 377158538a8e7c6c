#!/bin/bash
# The catch tolerance grid (25 palm offsets, ±20 mm in the palm's plane) of one
# hand design at fixed cells: Table 1 rows 1-5 and holdout-scraper-d330 at the
# cells the network of the 85 mm hand picked, six training objects of six
# geometries at their data-set label cell. Run from a checkout whose sdf/hand.sdf
# (and planner) is the design to measure; two streams for two cores.
#   bash studies/hand_design/measure.sh OUT_DIR [SCENARIO_FILE]
OUT=$1; SCEN=${2:-}
PY=${PYTHON:-.venv/bin/python}
mkdir -p "$OUT"
stream() { for j in $1; do IFS=: read -r o h d <<< "$j"
  $PY benchmarks/catch_tolerance.py "$o" "$h" "$d" --out "$OUT" ${SCEN:+--scenario "$SCEN"} \
    > "$OUT/$o.log" 2>&1; done; }
stream "table1-row1:0.28:-0.12 table1-row2:0.28:-0.12 table1-row3:0.28:-0.12 holdout-scraper-d330:0.28:-0.10 bracket-d200-3:0.20:-0.14 can-d150-4:0.20:-0.14" &
stream "table1-row4:0.28:-0.11 table1-row5:0.28:-0.11 flashlight-d200-1:0.20:-0.14 hammer-d150-3:0.20:-0.14 lollipop-d150-1:0.20:-0.14 stamp-d200-1:0.20:-0.14" &
wait
grep -h SUMMARY "$OUT"/*.log
