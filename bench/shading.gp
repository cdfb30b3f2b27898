# Charts for `scripts/bench.sh shading`: Cornell-box indirect error vs probe spacing and vs octahedral
# resolution, and error against shading cost (device ms per megapixel).
set datafile separator ','
set terminal pngcairo size 1400,420 font ',10' noenhanced
set output dir.'/shading.png'
set multiplot layout 1,3 title 'Shading from light-field probes vs path-traced reference on '.device
set title 'Cornell: error vs probe spacing (16x16 maps)'
set xlabel 'probe spacing (m)'
set ylabel 'indirect relative RMS'
set yrange [0:*]
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'cornell' && $4 == 16 ? $3 : 1/0):10 smooth unique with linespoints lw 2 title 'indirect'
set title 'Cornell: error vs map resolution (4x4x4 probes)'
set xlabel 'octahedral resolution (texels per side)'
set logscale x 2
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'cornell' && strcol(2) eq '4x4x4' ? $4 : 1/0):10 smooth unique with linespoints lw 2 title 'indirect'
unset logscale x
set title 'error against cost (all configurations)'
set xlabel 'probe shading ms per megapixel'
set key bottom right
plot dir.'/results.csv' every ::1 using 8:10:(sprintf('%s %s n%d', strcol(1), strcol(2), $4)) with labels offset 0,0.8 font ',8' notitle, \
     '' every ::1 using 8:10 with points pt 7 ps 1.2 title 'configuration'
unset multiplot
