# Charts for `scripts/bench.sh capture`: cost per probe vs Monte-Carlo noise, over samples per texel
# (16x16 maps) and over resolution (64 samples per texel).
set datafile separator ','
set terminal pngcairo size 1000,420 font ',10' noenhanced
set output dir.'/capture.png'
set multiplot layout 1,2 title 'Embree probe capture on '.device
set title 'samples per texel (16x16 maps)'
set xlabel 'samples per texel'
set logscale x 2
set ylabel 'ms per probe'
set y2label 'mean relative std error (%)'
set ytics nomirror
set y2tics
set yrange [0:*]
set y2range [0:*]
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'spp' ? $3 : 1/0):6 smooth unique with linespoints lw 2 title 'ms/probe', \
     '' every ::1 using (strcol(1) eq 'spp' ? $3 : 1/0):($8*100) smooth unique axes x1y2 with linespoints lw 2 dt 2 title 'rel std error'
set title 'resolution (64 samples per texel)'
set xlabel 'octahedral map resolution (texels per side)'
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'resolution' ? $2 : 1/0):6 smooth unique with linespoints lw 2 title 'ms/probe', \
     '' every ::1 using (strcol(1) eq 'resolution' ? $2 : 1/0):($8*100) smooth unique axes x1y2 with linespoints lw 2 dt 2 title 'rel std error'
unset multiplot
