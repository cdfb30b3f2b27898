#version 450
#define LFGI_VIR_LOD_SPLAT_FAR
#include "vir_lod_splat.glsl"
