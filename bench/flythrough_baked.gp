# Charts for `scripts/bench.sh flythrough_baked` (bench/flythrough_baked.sh): the fly-through charts of
# bench/flythrough.gp over the baked path cells of the 4 km world.
chart = 'flythrough_baked'
heading = 'Fly-through over baked cell files (4 km world, cells within 128 m of the line path), '
load 'bench/flythrough.gp'
