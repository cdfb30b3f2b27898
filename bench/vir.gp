# Charts for `scripts/bench.sh vir`: VIR vs cubemap rasterization on the same device and cell.
# results.csv columns: 1 method (vir_lod: VirPass default, LOD cut; vir_lod_relight: its splat kept; vir: full splat; cubemap), 2 resolution, 3 probes, 7 ms_per_probe, 8 probes_per_s,
# 15 dist_p90_rel_error, 16 dist_frac_off_5pct, 19 hole_fraction, 32 albedo_frac_off_0_05.
set datafile separator ','
set terminal pngcairo size 1100,460 font ',10' noenhanced
set key left top

# Throughput: probes/s vs probe count, per octahedral size N.
set output dir.'/vir_throughput.png'
set title 'probes/s on '.device.' (thick: VIR LOD; dash-dot: relight, splat kept; dotted: full splat; dashed: cubemap)'
set xlabel 'probes per run'
set ylabel 'probes per second'
set logscale xy
plot for [n in '8 16 32 64'] dir.'/results.csv' every ::1 \
       using ((strcol(1) eq 'vir_lod' && $2 == n+0) ? $3 : 1/0):8 with linespoints lw 3 lc (n+0 == 8 ? 1 : n+0 == 16 ? 2 : n+0 == 32 ? 3 : 4) pt 9 title 'VIR LOD N='.n, \
     for [n in '8 16 32 64'] dir.'/results.csv' every ::1 \
       using ((strcol(1) eq 'vir_lod_relight' && $2 == n+0) ? $3 : 1/0):8 with linespoints lw 1 dt 4 lc (n+0 == 8 ? 1 : n+0 == 16 ? 2 : n+0 == 32 ? 3 : 4) pt 8 title 'relight N='.n, \
     for [n in '8 16 32 64'] dir.'/results.csv' every ::1 \
       using ((strcol(1) eq 'vir' && $2 == n+0) ? $3 : 1/0):8 with linespoints lw 1 dt 3 lc (n+0 == 8 ? 1 : n+0 == 16 ? 2 : n+0 == 32 ? 3 : 4) pt 7 title 'VIR full N='.n, \
     for [n in '8 16 32 64'] dir.'/results.csv' every ::1 \
       using ((strcol(1) eq 'cubemap' && $2 == n+0) ? $3 : 1/0):8 with linespoints lw 2 dt 2 lc (n+0 == 8 ? 1 : n+0 == 16 ? 2 : n+0 == 32 ? 3 : 4) pt 5 title 'cubemap N='.n
unset logscale

# Error vs time: every measured configuration, ms per probe against the accuracy of its method and N
# (vs Embree closest hits along the texel-centre rays; lower-left is better). Median distance and normal
# errors are ~0 for both methods (flat surfaces are hit exactly), so the distance tails are plotted; the
# albedo panel shows what a coarse LOD cut costs where depths stay exact (merged nodes average albedo).
set terminal pngcairo size 1900,460 font ',10' noenhanced
set output dir.'/vir_error_vs_time.png'
unset title
set multiplot layout 1,4 title 'error vs time on '.device.' (labels: N; Embree texel-centre rays as reference)'
set logscale x
set xlabel 'GPU ms per probe (log)'
set yrange [0:*]
do for [panel = 1:4] {
  col = panel == 1 ? 16 : panel == 2 ? 15 : panel == 3 ? 19 : 32
  scale = 100
  set ylabel (panel == 1 ? 'texels with distance off by > 5 % (%)' : panel == 2 ? 'distance p90 relative error (%)' : \
              panel == 3 ? 'holes among texels that hit geometry (%)' : 'texels with albedo off by > 0.05 (%)')
  plot dir.'/results.csv' every ::1 using (strcol(1) eq 'vir_lod' ? $7 : 1/0):(column(col)*scale) with points pt 9 ps 1.5 lc 3 title 'VIR LOD', \
       '' every ::1 using (strcol(1) eq 'vir_lod' ? $7 : 1/0):(column(col)*scale):(sprintf('%d', $2)) with labels offset 0,1 notitle, \
       '' every ::1 using (strcol(1) eq 'vir' ? $7 : 1/0):(column(col)*scale) with points pt 7 ps 1.3 lc 1 title 'VIR full splat', \
       '' every ::1 using (strcol(1) eq 'vir' ? $7 : 1/0):(column(col)*scale):(sprintf('%d', $2)) with labels offset 0,1 notitle, \
       '' every ::1 using (strcol(1) eq 'cubemap' ? $7 : 1/0):(column(col)*scale) with points pt 5 ps 1.3 lc 2 title 'cubemap', \
       '' every ::1 using (strcol(1) eq 'cubemap' ? $7 : 1/0):(column(col)*scale):(sprintf('%d', $2)) with labels offset 0,-1 notitle
}
unset multiplot
