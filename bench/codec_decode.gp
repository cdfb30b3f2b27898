# Charts for `scripts/bench.sh codec_decode`: generator decode cost per probe by batch size (speed), the
# fraction of the device's GEMM ceiling reached, and error vs the reference decoder against cost (accuracy).
# results.csv columns: 1 model, 2 out_res, 3 mflop_per_probe, 4 method, 5 batch_probes, 6 decode_us_per_probe,
# 7 probes_per_s, 8 gflops, 9 fraction_of_ceiling, 10 ceiling_gflops, 11 max_rel_error_vs_reference
set datafile separator ','
set terminal pngcairo size 1500,460 font ',10' noenhanced
set output dir.'/codec_decode.png'
set multiplot layout 1,3 title 'Generator decode on '.device.' (GPU) and OpenBLAS (CPU)'
models = 'small_16px medium_16px large_32px'
methods = 'cpu_reference cpu_sgemm gpu_rowstrip gpu_tiled'
sel(m, k, col) = (strcol(1) eq m && strcol(4) eq k) ? column(col) : 1/0

set title 'Decode cost per probe'
set xlabel 'batch (probes)'
set ylabel 'us / probe (log)'
set logscale xy
set key top right font ',8'
plot for [m in models] for [k in methods] dir.'/results.csv' every ::1 using (sel(m, k, 5)):(sel(m, k, 6)) \
     with linespoints lw 1.5 title m.' '.k

set title 'Fraction of the same device''s GEMM ceiling'
set ylabel 'decode GFLOP/s / GEMM GFLOP/s'
unset logscale y
set yrange [0:*]
set logscale x
plot for [m in models] for [k in 'cpu_sgemm gpu_rowstrip gpu_tiled'] dir.'/results.csv' every ::1 \
     using (sel(m, k, 5)):(sel(m, k, 9)) with linespoints lw 1.5 title m.' '.k, 0.5 with lines dt 2 lc 'gray' title 'goal 50 %'

set title 'Accuracy vs cost (error vs CPU reference decoder)'
set xlabel 'us / probe (log)'
set ylabel 'max |y - y_ref| / max |y_ref| (log)'
set yrange [*:*]
set logscale xy
set format y '%.0e'
plot for [k in 'cpu_sgemm gpu_rowstrip gpu_tiled'] dir.'/results.csv' every ::1 \
     using (strcol(4) eq k ? $6 : 1/0):(strcol(4) eq k ? $11 : 1/0) with points pt 7 ps 1.2 title k
unset multiplot
