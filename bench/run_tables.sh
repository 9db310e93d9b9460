#!/usr/bin/env bash
# Reproduce the OMG paper's Tables I, II, III and Fig. 8 (Sec. IV) with pickplan's bench commands.
#   bench/run_tables.sh            quick CI setting (4 scenes, 1 run), built-in objects
#   FULL=1 bench/run_tables.sh     the paper's setting (100 scenes, 30 grasps, 10 runs) on YCB objects
# Environment: PY (default .venv/bin/python), OUT (default out/bench), YCB (default ../shared/data/ycb),
#              WORKERS (default 2), RAY (a Ray address or "local"; default: local process pool).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
OUT=${OUT:-out/bench}
YCB=${YCB:-../shared/data/ycb}
WORKERS=${WORKERS:-2}
extra=(--workers "$WORKERS")
[ -n "${RAY:-}" ] && extra+=(--ray "$RAY")
if [ -n "${FULL:-}" ]; then
  size=(--scenes 100 --runs 10 --objects "$YCB")
  mkdir -p "$OUT"
  # one scene set for every table: generated once by the first sweep, then shared
  $PY -m pickplan bench selection "${size[@]}" "${extra[@]}" --out "$OUT/selection"
  scenes=(--scene-dir "$OUT/selection/scenes" --runs 10)
  $PY -m pickplan bench planners "${scenes[@]}" "${extra[@]}" --out "$OUT/planners"
  $PY -m pickplan bench refinement "${scenes[@]}" --grasps 60 "${extra[@]}" --out "$OUT/refinement"
  $PY -m pickplan bench ablation "${scenes[@]}" "${extra[@]}" --out "$OUT/ablation"
else
  for t in selection planners refinement ablation; do
    $PY -m pickplan bench "$t" --quick "${extra[@]}" --out "$OUT/quick_$t"
  done
fi
