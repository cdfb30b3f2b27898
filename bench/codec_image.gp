# Charts for `scripts/bench.sh codec_image`: every method's "all" row (bytes over all active probes, image
# error the mean over the image scenes, leak the worst wall). One point per method + visibility.
set datafile separator ','
set format x '%g'
set format y '%g'
set terminal pngcairo size 1500,480 font ',10' noenhanced
csv = dir.'/results.csv'
labels = system("awk -F, 'NR > 1 && $1 == \"all\" { print $5 }' ".csv." | tr '\\n' ' '")
# columns: 1 scene, 5 label, 8 bytes_per_probe, 9 decode_us_per_probe, 11 indirect_rel_rms, 12 leak_ratio
row(l) = sprintf("< awk -F, '$1 == \"all\" && $5 == \"%s\"' %s", l, csv)

set output dir.'/codec_image.png'
set multiplot layout 1,3 title 'Probe codecs judged on the shaded image, '.device.' (0 B = nothing stored)'
set key outside bottom center horizontal maxrows 4 font ',8'
set logscale x
set title 'indirect image error vs size'
set xlabel 'bytes per probe + 1 (all-in, log)'
set ylabel 'indirect relative RMS vs path tracer (mean over scenes)'
plot for [i=1:words(labels)] row(word(labels, i)) using ($8 + 1):11 with points pt (4 + i % 9) lc i ps 1.5 title word(labels, i)
set title 'indirect image error vs decode time'
set xlabel 'CPU decode us per probe (VIR rows: device time, log)'
plot for [i=1:words(labels)] row(word(labels, i)) using ($9 > 0 ? $9 : 0.01):11 with points pt (4 + i % 9) lc i ps 1.5 title word(labels, i)
set title 'leak: sealed room / sunlit room (worst wall)'
set xlabel 'bytes per probe + 1 (all-in, log)'
set ylabel 'leak ratio (log, floor 1e-6)'
set logscale y
set arrow from graph 0, first 0.01 to graph 1, first 0.01 nohead dt 2
plot for [i=1:words(labels)] row(word(labels, i)) using ($8 + 1):($12 > 1e-6 ? $12 : 1e-6) with points pt (4 + i % 9) lc i ps 1.5 title word(labels, i)
unset multiplot
