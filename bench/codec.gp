# Charts for `scripts/bench.sh codec`: rate-distortion-speed of the probe codecs, from the "all" rows
# (bytes pooled over the scenes, errors the mean of the per-scene errors). One line per codec family; a
# "gan" family appears once the generative codec is in the run.
set datafile separator ','
set format x '%g'
set format y '%g'
set terminal pngcairo size 1200,480 font ',10' noenhanced
csv = dir.'/results.csv'
# the families present (a family without rows would abort the plot)
families = system("awk -F, 'NR > 1 && $1 == \"all\" { print $4 }' ".csv." | sort -u | tr '\\n' ' '")
# columns: 1 scene, 4 family, 7 bytes_per_probe, 8 irr_rel_rms, 10 rad_psnr_db, 12 decode_us_per_probe,
# 14 irr_codec_rel_rms
# one family's "all" rows, sorted by bytes (a filter with 1/0 would break the lines between settings)
rows(f) = sprintf("< awk -F, '$1 == \"all\" && $4 == \"%s\"' %s | sort -t, -k7 -g", f, csv)

set output dir.'/codec.png'
set multiplot layout 1,2 title 'Probe codecs on '.device.' (16x16 radiance, 8x8 irradiance, all scenes)'
set title 'irradiance error vs size'
set xlabel 'bytes per probe (all-in, log)'
set ylabel 'irradiance relative RMS (log)'
set logscale xy
set key top right
plot for [f in families] rows(f) using 7:8 with linespoints lw 2 pt 7 title f
set title 'irradiance error vs decode time'
set xlabel 'CPU decode us per probe (1 thread, log)'
plot for [f in families] rows(f) using 12:8 with linespoints lw 2 pt 7 title f
unset multiplot

set output dir.'/codec_extra.png'
set multiplot layout 1,2 title 'Probe codecs on '.device.' (all scenes)'
set title "codec's own irradiance loss vs size (vs the uncompressed radiance's irradiance)"
set xlabel 'bytes per probe (all-in, log)'
set ylabel 'irradiance relative RMS vs float radiance (log)'
set logscale xy
plot for [f in families] rows(f) using 7:(f eq 'reference_fp32' ? 1/0 : $14) with linespoints lw 2 pt 7 title f
set title 'radiance PSNR vs size'
set ylabel 'radiance PSNR (dB, peak = scene max)'
unset logscale
set logscale x
plot for [f in families] rows(f) using 7:(f eq 'reference_fp32' ? 1/0 : $10) with linespoints lw 2 pt 7 title f
unset multiplot
