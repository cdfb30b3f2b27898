# Charts for `scripts/bench.sh ceilings`: the GEMM kernel's speed (cost) and error vs OpenBLAS (accuracy)
# by size, and the measured ceilings.
set datafile separator ','
set terminal pngcairo size 1000,420 font ',10' noenhanced
set output dir.'/ceilings.png'
set multiplot layout 1,2 title 'Machine ceilings on '.device
set title 'GPU GEMM (rowstrip kernel): speed and accuracy'
set xlabel 'matrix size N (N x N x N)'
set ylabel 'GFLOP/s'
set yrange [0:*]
set y2label 'max |C - C(OpenBLAS)| / max|C|'
set logscale y2
set format y2 '%.0e'
set ytics nomirror
set y2tics
set key top left
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'gemm_rowstrip' ? $2 : 1/0):3 with linespoints lw 2 title 'GFLOP/s', \
     '' every ::1 using (strcol(1) eq 'gemm_rowstrip' ? $2 : 1/0):5 axes x1y2 with linespoints lw 2 dt 2 title 'max rel error'
unset y2label
unset y2tics
unset logscale y2
set yrange [*:*]
set title 'Ceilings (units in labels)'
set style fill solid 0.6
set boxwidth 0.6
set xlabel ''
set ylabel 'value (log scale)'
set logscale y
set xtics rotate by -30
set xrange [-0.5:4.5]
# rows 1..5 of results.csv are the five ceilings (the GEMM sweep follows them)
plot dir.'/results.csv' every ::1::5 using 0:3:xtic(strcol(1).' ['.strcol(4).']') with boxes notitle
unset multiplot
