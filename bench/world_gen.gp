# Charts for `scripts/bench.sh world_gen`: memory while generating every cell (must stay flat), and the
# build phase's cost per cell against its accuracy (surfel area vs mesh area).
set datafile separator ','
set terminal pngcairo size 1000,420 font ',10' noenhanced
set output dir.'/world_gen.png'
set multiplot layout 1,2 title 'Synthetic world generation on '.device
set title 'generate every cell: resident memory'
set xlabel 'cells generated'
set ylabel 'resident memory (MB)'
set y2label 'elapsed (s)'
set yrange [0:*]
set ytics nomirror
set y2tics
set key bottom right
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'generate' ? $2 : 1/0):4 with lines lw 2 title 'RSS (MB)', \
     '' every ::1 using (strcol(1) eq 'generate' ? $2 : 1/0):3 axes x1y2 with lines lw 2 dt 2 title 'elapsed (s)'
set title 'build (probes + surfels): cost vs accuracy per cell'
set xlabel 'surfels in cell'
set ylabel 'surfel area / mesh area - 1 (abs)'
unset y2label
unset y2tics
set logscale y
set format y '%.0e'
set yrange [*:*]
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'build' ? $6 : 1/0):($8 > 0 ? $8 : 1e-9) with points pt 7 title 'cells'
unset multiplot
