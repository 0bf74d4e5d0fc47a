# Step throughput against Bullet's deformable solver, from docs/bench/bullet_step.json (the rotated
# start): gnuplot -e "in='docs/bench/bullet_step.json'; out='docs/bench/bullet_step.png'" scripts/bench_plot.gp
set terminal pngcairo size 640,400 font ",10"
set output out
set logscale xy
set xlabel "tets"
set ylabel "tet-steps per second, 1 thread"
set format y "%.0e"
set key bottom left
set grid
set xrange [800:1.5e6]
set yrange [2e5:1e8]
# a line per box: tets, then cutsim double, cutsim single, Bullet, Bullet damped
rows = "< python3 -c 'import json, sys\nfor r in json.load(open(sys.argv[1]))[\"runs\"]:\n    t = r[\"tet_steps_per_second\"]\n    print(r[\"tets\"], t[\"cutsim_double\"], t[\"cutsim_single\"], t[\"bullet\"], t[\"bullet_damped\"])' ".in
plot rows using 1:2 with linespoints lw 2 pt 7 title "cutsim, double", \
     rows using 1:3 with linespoints lw 2 pt 5 title "cutsim, single", \
     rows using 1:4 with linespoints lw 2 pt 9 title "Bullet, damping 0", \
     rows using 1:5 with linespoints lw 2 pt 11 title "Bullet, default damping"
