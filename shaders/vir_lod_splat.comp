#version 450
#include "vir_lod_splat.glsl"
