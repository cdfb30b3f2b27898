# Charts for `scripts/bench.sh codec_decode`: generator decode cost per probe by batch size (speed), the
# fraction of the same device's GEMM ceiling (per process-CPU second: the meaningful basis on lavapipe and a
# shared machine; and per wall/device second: the basis on a real GPU), and error vs the reference decoder
# against cost (accuracy). results.csv columns: 1 model, 2 out_res, 3 mflop_per_probe, 4 method,
# 5 batch_probes, 6 decode_us_per_probe, 7 probes_per_s, 8 gflops, 9 fraction_of_ceiling, 10 ceiling_gflops,
# 11 gflops_per_cpu_s, 12 fraction_of_ceiling_cpu_time, 13 ceiling_gflops_per_cpu_s, 14 max_rel_error_vs_reference
set datafile separator ','
set terminal pngcairo size 1400,900 font ',10' noenhanced
set output dir.'/codec_decode.png'
set multiplot layout 2,2 title 'Generator decode on '.device.' (GPU kernels) and OpenBLAS (CPU)'
models = 'small_16px medium_16px large_32px'
methods = 'cpu_reference cpu_sgemm gpu_rowstrip gpu_tiled'
sel(m, k, col) = (strcol(1) eq m && strcol(4) eq k) ? column(col) : 1/0
pt(k) = k eq 'cpu_reference' ? 1 : k eq 'cpu_sgemm' ? 7 : k eq 'gpu_rowstrip' ? 5 : 9
lc(m) = m eq 'small_16px' ? 1 : m eq 'medium_16px' ? 2 : 3

set title 'Decode cost per probe (wall / device time)'
set xlabel 'batch (probes)'
set ylabel 'us / probe (log)'
set logscale xy
set key outside right font ',8'
plot for [m in models] for [k in methods] dir.'/results.csv' every ::1 using (sel(m, k, 5)):(sel(m, k, 6)) \
     with points pt pt(k) ps 1.3 lc lc(m) title m.' '.k

set title 'Accuracy vs cost (error vs the CPU reference decoder)'
set xlabel 'us / probe (log)'
set ylabel 'max |y - y_ref| / max |y_ref| (log)'
set format y '%.0e'
plot for [k in 'cpu_sgemm gpu_rowstrip gpu_tiled'] dir.'/results.csv' every ::1 \
     using (strcol(4) eq k ? $6 : 1/0):(strcol(4) eq k ? $14 : 1/0) with points pt pt(k) ps 1.3 title k
set format y '%g'

set title 'Fraction of GEMM ceiling, per process-CPU second (lavapipe basis)'
set xlabel 'batch (probes)'
set ylabel 'decode GFLOP/CPU-s / GEMM GFLOP/CPU-s'
unset logscale y
set yrange [0:1.1]
set logscale x
plot for [m in models] for [k in 'cpu_sgemm gpu_rowstrip gpu_tiled'] dir.'/results.csv' every ::1 \
     using (sel(m, k, 5)):(sel(m, k, 12)) with points pt pt(k) ps 1.3 lc lc(m) title m.' '.k, \
     0.5 with lines dt 2 lc 'gray' title 'goal 50 %'

set title 'Fraction of GEMM ceiling, per wall / device second (real-GPU basis; noisy on a shared CPU)'
set ylabel 'decode GFLOP/s / GEMM GFLOP/s'
set yrange [0:*]
plot for [m in models] for [k in 'cpu_sgemm gpu_rowstrip gpu_tiled'] dir.'/results.csv' every ::1 \
     using (sel(m, k, 5)):(sel(m, k, 9)) with points pt pt(k) ps 1.3 lc lc(m) title m.' '.k, \
     0.5 with lines dt 2 lc 'gray' title 'goal 50 %'
unset multiplot
