#!/usr/bin/env bash
# Regenerates the raw outputs in docs/bench with the commands BENCHMARKS.md quotes, then the page's
# tables drawn from them (scripts/bench_tables.py).
#   scripts/bench.sh               the short benchmarks (about 15 minutes on 2 cores)
#   scripts/bench.sh --accuracy    and the default accuracy run (about 3 minutes more)
#   scripts/bench.sh --long        and the two 1% accuracy runs, the 500 random cut sequences, the
#                                  thread count on a 40k-tet liver and liver_hires.json (about 2.6
#                                  hours more)
# Needs a Release build with the benchmarks (scripts/build.sh, or CUTSIM_BUILD=DIR for another
# build folder). Run it on an otherwise idle machine: every number is a wall time.
set -euo pipefail
cd "$(dirname "$0")/.."
B=${CUTSIM_BUILD:-build}
D=docs/bench
accuracy=0
long=0
for arg in "$@"; do
  case "$arg" in
    --accuracy) accuracy=1 ;;
    --long) accuracy=1; long=1 ;;
    *) echo "usage: scripts/bench.sh [--accuracy | --long]" >&2; exit 2 ;;
  esac
done
# the third-party meshes' folder, as configured for the build
data=$(sed -n 's/^CUTSIM_DATA_DIR:PATH=//p' "$B/CMakeCache.txt")
cmake --build "$B" --target cutsim cutsim_bench cutsim_bullet_bench -j"$(nproc)"

# step throughput, and beside Bullet's deformable-body solver (one thread, taking turns)
"$B/cutsim" bench step --seconds 2 --json --csv "$D/step.csv" > "$D/step.json"
"$B/bench/cutsim_bullet_bench" --seconds 1 --rounds 5 --json > "$D/bullet_step.json"
"$B/bench/cutsim_bullet_bench" --seconds 1 --rounds 3 --unrotated --json > "$D/bullet_step_unrotated.json"
gnuplot -e "in='$D/bullet_step.json'; out='$D/bullet_step.png'" scripts/bench_plot.gp
# the thread count a run picks: 1, 2 and measured, taking turns, then with a loop on the other core
"$B/cutsim" bench threads assets/scenes/bar_sag.json --set 'object.box.cells=[36,8,6]' --set duration=1.0 \
  --rounds 3 --busy --json --csv "$D/threads.csv" > "$D/threads.json"

# stable steps: Table 4.3 (liver and armadillo), stability sweeps and random cuts
{ "$B/cutsim" dt assets/meshes/liver.msh --scale 0.0254 --worst 5
  echo
  bin=$(cd "$B" && pwd)/cutsim  # run from the data folder, so the output names the mesh only
  (cd "$data/tet" && "$bin" dt sofa_Armadillo_Tetra_4406.gmsh22.msh --scale 0.01 --worst 5); } > "$D/dt_table43.txt"
"$B/cutsim" dt assets/meshes/liver.msh --scale 0.0254 --json > "$D/dt_liver.json"
(cd "$data/tet" && "$bin" dt sofa_Armadillo_Tetra_4406.gmsh22.msh --scale 0.01 --json) > "$D/dt_armadillo.json"
"$B/cutsim" bench stability --json > "$D/stability.json"

# mesh improvement against TetGen's and Gmsh's optimisers (thesis Table 5.1)
"$B/cutsim" bench improve --plot "$D/improve.png" --json > "$D/improve.json"
"$B/cutsim" bench improve --speed --json > "$D/improve_speed.json"

# Table 6.1 (mesh intersection against conforming cuts), and the cut moved through its cell
"$B/cutsim" bench mi-bar > "$D/mi_bar.txt"
"$B/cutsim" bench mi-bar --json > "$D/mi_bar.json"
"$B/cutsim" bench mi-bar --sweep 12 > "$D/mi_bar_sweep.txt"

# the thesis's four liver cuts: the exact step after each, XFEM against the baselines (report.json compare)
"$B/cutsim" run assets/scenes/liver_cuts.json --out captures/liver_cuts --no-render --quiet
cp captures/liver_cuts/report.json "$D/liver_cuts.json"

# the step through four plane cuts per cutting method (thesis Tables 5.5 and 5.6)
"$B/cutsim" bench cutstep --json > "$D/cutstep.json"
# subdivision+improve's budget against its step: three runs of each setting and of the unbudgeted one
{ for s in "" "--problems 10000 --free-nodes 80" "--problems 20000 --free-nodes 160"; do
    for k in 1 2 3; do "$B/cutsim" bench cutstep --only subdivision+improve $s --json; done
  done
  for k in 1 2 3; do "$B/cutsim" bench cutstep --only subdivision+improve-full --json; done; } |
  python3 -c '
import json, sys
text, runs, at = sys.stdin.read(), [], 0
while text[at:].strip():
    at = len(text) - len(text[at:].lstrip())
    run, at = json.JSONDecoder().raw_decode(text, at)
    runs.append(run)
print(json.dumps(runs, indent=2))' > "$D/cutstep_budget.json"

# per-stage cost of a scene
"$B/cutsim" bench cost assets/scenes/bar_sag.json --set duration=0.5 --json --csv "$D/cost.csv" > "$D/cost.json"

# contact: its cost against the contact points, the penalty model's depth against its stiffness,
# the contact stage of the scenes with a tool; a probe on a 20k-tet liver at a haptic rate
"$B/cutsim" bench contact --plot "$D/contact.png" --json --csv "$D/contact.csv" > "$D/contact.json"
for s in probe demo_mi demo blade; do
  "$B/cutsim" bench cost "assets/scenes/$s.json" --set output.vtu=false --threads 1 --json \
    --csv "$D/cost_$s.csv" > "$D/cost_$s.json"
done
"$B/cutsim" bench haptic --json --csv "$D/haptic.csv" > "$D/haptic.json"
# capture as a user gets it (PNGs, video, HUD), two runs of two scenes
"$B/cutsim" bench capture assets/scenes/demo.json assets/scenes/blade.json --runs 2 --json \
  --csv "$D/capture.csv" > "$D/capture.json"
# cutsim tetra on the data folder's surfaces it was not tuned for (about a minute)
scripts/bench_runs.py --cutsim "$B/cutsim" --data "$data" tetra > "$D/tetra_heldout.json"

# stepping from Python against the CLI (taking turns, fresh processes)
cmake --build "$B" --target cutsim_py -j"$(nproc)"
PYTHONPATH="$B/python" /usr/bin/python3 scripts/bench_python.py --cutsim "$B/cutsim" --rounds 21 > "$D/python_step.txt"

# cut latency, time-step estimators, contact (Google Benchmark)
"$B/bench/cutsim_bench" --benchmark_filter='Cut|Timestep|Contact' --benchmark_repetitions=5 \
  --benchmark_report_aggregates_only=true > "$D/cutsim_bench.txt"

if [ "$accuracy" = 1 ]; then
  # what each route after a cut costs in accuracy: the notched cantilever alone
  "$B/cutsim" bench accuracy --only notch-lumping --json > "$D/accuracy_notch.json"
  "$B/cutsim" bench accuracy --json --csv "$D/accuracy.csv" --plot "$D/accuracy.png" > "$D/accuracy.json"
  "$B/cutsim" bench accuracy --from "$D/accuracy.csv" > "$D/accuracy.txt"
fi
if [ "$long" = 1 ]; then
  # the 1% sweep: finer bars and references, backward Euler (LDL^T) in full up to N = 8 (45 min)
  "$B/cutsim" bench accuracy --res 2,4,6,8,12,14 --implicit-max-res 8 --ref-levels 8,12,16 --only cantilever \
    --json --csv "$D/accuracy_1pct.csv" > "$D/accuracy_1pct.json"
  "$B/cutsim" bench accuracy --from "$D/accuracy_1pct.csv" --plot "$D/accuracy_1pct.png" > "$D/accuracy_1pct.txt"
  # the 1% comparison against backward Euler with CG, the two sides taking turns (61 min)
  "$B/cutsim" bench accuracy --res 12 --implicit-max-res 0 --cg-max-res 12 --ref-levels 8,12,16 --only cantilever \
    --json --csv "$D/accuracy_1pct_paired.csv" > "$D/accuracy_1pct_paired.json"
  "$B/cutsim" bench accuracy --from "$D/accuracy_1pct_paired.csv" > "$D/accuracy_1pct_paired.txt"
  # the step floor through 500 random cut sequences per object (the stress test, about 4 minutes)
  cmake --build "$B" --target stress_cut -j"$(nproc)"
  CUTSIM_STRESS_JSON="$D/random_cuts_500.json" "$B/tests/stress_cut" --gtest_filter=RandomCutsStress.FloorHolds500
  # the thread count on the improved 39,630-tet TetGen liver under the probe (about 15 minutes; tetgen on PATH)
  awk '/^v /{v[++n]=$2" "$3" "$4} /^f /{f[++m]="3 "$2-1" "$3-1" "$4-1}
       END{print "OFF"; print n" "m" 0"; for(i=1;i<=n;i++) print v[i]; for(i=1;i<=m;i++) print f[i]}' \
    assets/meshes/sofa_liver.obj > captures/sofa_liver.off
  tetgen -pq1.4a0.004 -Q captures/sofa_liver.off
  "$B/cutsim" improve captures/sofa_liver.1.node --out captures/liver_0.004.msh --quiet > /dev/null
  "$B/cutsim" bench threads assets/scenes/probe.json --rounds 2 --busy \
    --set 'object={"mesh": "../../captures/liver_0.004.msh", "scale": 0.0254, "visual": "../meshes/sofa_liver-smooth.obj"}' \
    --json --csv "$D/threads_liver.csv" > "$D/threads_liver.json"
  # the shipped high-resolution scene with its frames, one thread (about 5 minutes)
  scripts/bench_runs.py --cutsim "$B/cutsim" run assets/scenes/liver_hires.json --out captures/hires --threads 1 \
    > "$D/liver_hires.json"
  # the same scene at three mesh sizes without frames (about 6 minutes), and blade.json's stroke on
  # finer livers and lattices (about 17 minutes on an AVX2 machine; a diverged run is recorded, not fatal)
  scripts/bench_runs.py --cutsim "$B/cutsim" runs assets/scenes/liver_hires.json --out captures/hires_sizes \
    --vary object.tetra.size=0.0046,0.0038,0.0030 --no-render --threads 1 > "$D/liver_hires_sizes.json" || true
  scripts/bench_runs.py --cutsim "$B/cutsim" blade-scale --out captures/blade_scale > "$D/blade_scale.json" || true
fi
# BENCHMARKS.md's tables drawn from the JSON results
python3 scripts/bench_tables.py
echo "docs/bench regenerated, BENCHMARKS.md's generated tables rewritten"
