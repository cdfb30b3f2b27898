# Charts for `scripts/bench.sh shading`: Cornell-box indirect error vs probe spacing and vs octahedral
# resolution (capture and VIR probes), and error against the cost of producing the probes per source
# (column 12: capture | vir | codec; Cornell and the world cell).
set datafile separator ','
set terminal pngcairo size 1400,420 font ',10' noenhanced
set output dir.'/shading.png'
set multiplot layout 1,3 title 'Shading from light-field probes vs path-traced reference on '.device
set title 'Cornell: error vs probe spacing (16x16 maps)'
set xlabel 'probe spacing (m)'
set ylabel 'indirect relative RMS'
set yrange [0:*]
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'cornell' && $4 == 16 && strcol(12) eq 'capture' ? $3 : 1/0):10 smooth unique with linespoints lw 2 title 'capture', \
     '' every ::1 using (strcol(1) eq 'cornell' && $4 == 16 && strcol(12) eq 'vir' ? $3 : 1/0):10 smooth unique with linespoints lw 2 title 'vir'
set title 'Cornell: error vs map resolution (4x4x4 probes)'
set xlabel 'octahedral resolution (texels per side)'
set logscale x 2
plot dir.'/results.csv' every ::1 using (strcol(1) eq 'cornell' && strcol(2) eq '4x4x4' && strcol(12) eq 'capture' ? $4 : 1/0):10 smooth unique with linespoints lw 2 title 'capture', \
     '' every ::1 using (strcol(1) eq 'cornell' && strcol(2) eq '4x4x4' && strcol(12) eq 'vir' ? $4 : 1/0):10 smooth unique with linespoints lw 2 title 'vir'
unset logscale x
set title 'error against the cost of the probes, per source'
set xlabel 'seconds to produce the probes (capture / VIR frames / decode)'
set logscale x
set key top right
plot dir.'/results.csv' every ::1 using 6:10:(sprintf('%s %s %s', strcol(1), strcol(2), strcol(12))) with labels offset 0,0.8 font ',7' notitle, \
     '' every ::1 using (strcol(12) eq 'capture' ? $6 : 1/0):10 with points pt 7 ps 1.2 title 'capture', \
     '' every ::1 using (strcol(12) eq 'vir' ? $6 : 1/0):10 with points pt 5 ps 1.2 title 'vir', \
     '' every ::1 using (strcol(12) eq 'codec' ? $6 : 1/0):10 with points pt 9 ps 1.4 title 'codec'
unset logscale x
unset multiplot
