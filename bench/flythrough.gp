# Charts for `scripts/bench.sh flythrough`: fallback coverage vs camera speed (the accuracy side) next to
# frame cost vs speed, and the 50 m/s flight frame by frame. bench/flythrough_baked.gp sets `chart` and
# `heading` and loads this file (same columns).
if (!exists("chart")) chart = 'flythrough'
if (!exists("heading")) heading = 'Streaming fly-through, 16.8 km2 synthetic world, '
set datafile separator ','
set terminal pngcairo size 1200,800 font ',10' noenhanced
set output dir.'/'.chart.'.png'
set multiplot layout 2,2 title heading.device
set logscale x
set xlabel 'camera speed (m/s)'
set ylabel 'fallback fraction of visible samples (%)'
set key top left
plot dir.'/results.csv' every ::1 using 1:($4*100) with linespoints lw 2 pt 7 title 'fallback %', 1 with lines dt 2 title '1 % goal'
set ylabel 'ms'
plot dir.'/results.csv' every ::1 using 1:7 with linespoints lw 2 pt 7 title 'p99 frame', \
     '' every ::1 using 1:5 with linespoints pt 6 title 'p50 frame', '' every ::1 using 1:8 with linespoints pt 5 title 'p99 update'
unset logscale x
set xlabel 'frame (50 m/s flight)'
set ylabel 'resident MB'
set y2label 'cells'
set ytics nomirror
set y2tics
plot dir.'/frames.csv' every ::1 using 1:($4/1e6) with lines lw 2 title 'resident MB', '' every ::1 using 1:2 axes x1y2 with lines title 'resident cells'
unset y2label
unset y2tics
set ylabel 'ms'
set logscale y
plot dir.'/frames.csv' every ::1 using 1:5 with lines title 'update (game thread)', '' every ::1 using 1:6 with lines title 'shade samples', \
     '' every ::1 using 1:8 with impulses title 'load on IO thread (read + decode)', '' every ::1 using 1:10 with impulses title 'relight on IO thread'
unset logscale y
unset multiplot
