# bench bake: projected world bake hours vs world size on 1 and 32 nodes (from plan.csv), log-log.
# gnuplot -e "dir='out/bench/bake'; device='...'" bench/bake.gp
set datafile separator ","
set terminal pngcairo size 900,560 font ",11"
set output dir."/projected_hours.png"
set title "lfgi bake: projected hours by world size (measured s/cell by kind x kind mix) - ".device
set xlabel "world area (km^2)"
set ylabel "projected bake time (hours)"
set logscale xy
set grid
set key top left
set xrange [10:600]
# plan.csv holds two rows per size (1 node, then 32 nodes): every other row is one line.
plot dir."/plan.csv" skip 1 every 2::0 using 3:11 with linespoints lw 2 pt 7 title "1 node", \
     dir."/plan.csv" skip 1 every 2::1 using 3:11 with linespoints lw 2 pt 5 title "32 nodes"
