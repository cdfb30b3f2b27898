# Charts for `scripts/bench.sh stability`: leak ratio vs wall thickness and vs probe spacing per method,
# irradiance error of the generator at lighting it never saw (vs key baselines), flicker per time-of-day
# step. Columns: 1 section, 2 method, 3 wall_m, 4 spacing_m, 5 probe_setup, 6 chebyshev, 7 time_h,
# 8 overcast, 9 metric, 10 value. Rows are selected with grep (a filtered-out row would break the lines).
# Leak ratios are floored at 1e-9 on the log axis (exact zeros).
set datafile separator ','
set terminal pngcairo size 1500,900 font ',10' noenhanced
set output dir.'/stability.png'
set multiplot layout 2,2 title 'Failure modes on '.device
f(x) = x > 1e-9 ? x : 1e-9
# rows(section, method, wall, spacing, setup, chebyshev, metric): a grep over results.csv ('[^,]*' = any).
rows(sec, m, w, s, setup, cheb, metric) = sprintf('< grep -E "^%s,%s,%s,%s,%s,%s,[^,]*,[^,]*,%s," "%s/results.csv"', \
                                                  sec, m, w, s, setup, cheb, metric, dir)
any = '[^,]*'

set title 'light leak vs wall thickness (1 m spacing, probes straddling the wall)'
set xlabel 'wall thickness (m)'
set ylabel 'leak ratio (dark room / sunlit room indirect)'
set logscale y
set logscale x
set key outside right font ',8'
plot for [m in 'raw_fp16 sh_l2 generator vir_relight vir_relight_dense'] rows('leak', m, any, '1', 'straddle\+relocation', 'on', 'leak_ratio') \
       using 3:(f($10)) with linespoints lw 2 title m.' Chebyshev', \
     for [m in 'raw_fp16 vir_relight'] rows('leak', m, any, '1', 'straddle\+relocation', 'off', 'leak_ratio') \
       using 3:(f($10)) with linespoints dt 2 title m.' no Chebyshev', \
     rows('leak', 'raw_fp16', any, '1', 'in_wall\+relocation', 'on', 'leak_ratio') \
       using 3:(f($10)) with linespoints dt 3 lw 2 title 'raw_fp16 probe plane in the wall, relocated', \
     0.01 with lines lc 'black' dt 4 title '1 % goal'
unset logscale x

set title 'light leak vs probe spacing (0.1 m wall, probes straddling it, relocation on, Chebyshev on)'
set xlabel 'probe spacing (m)'
set logscale x 2
plot for [m in 'raw_fp16 sh_l2 generator vir_relight vir_relight_dense'] rows('leak', m, '0.1', any, 'straddle\+relocation', 'on', 'leak_ratio') \
       using 4:(f($10)) with linespoints lw 2 title m, \
     0.01 with lines lc 'black' dt 4 title '1 % goal'
unset logscale x

set title 'lighting never trained on (keys 8, 12, 17.5 h; overcast shown at 12.5 h)'
set xlabel 'time of day (h)'
set ylabel 'irradiance relative RMS vs capture (log; key baselines are 0 at their keys)'
set xrange [5:21]
plot for [m in 'generator nearest_key key_blend'] rows('unseen', m, any, any, any, any, 'irr_rel_rms') \
       using ($7 + 0.5 * $8):10 with points pt 7 ps 1.3 title m
set xrange [*:*]
unset logscale y
set yrange [0:*]

set title 'flicker of a static view per 0.1 h time-of-day step'
set xlabel 'time of day (h)'
set ylabel 'mean |I(k) - I(k-1)| / mean I'
plot for [m in 'capture_truth decode_only vir_relight'] rows('flicker', m, any, any, any, any, 'flicker_rel') \
       using 7:10 with linespoints lw 2 title m
unset multiplot
