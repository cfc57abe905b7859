#version 330 core
// terratheme packed layer read on the GPU (docs/gpu.md "Packed layers"): each
// fragment looks up one texel of the packed layer (tt_packed.glsl).
//
// Defines:
//   TT_POINTS  0: fragment (i, j) of the target reads texel tt_origin + (i, j)
//              (a block of the index grid, for the blend shader's tt_grid;
//              256 outside the layer is written 255);
//              1: fragment (i, j) reads the texel whose coordinates are texel
//              (i, j) of tt_points (RG32I), and writes 256 outside the layer
//              (lookups of any coordinates, checked against the CPU's)
// Uniforms: tt_origin ivec2 (TT_POINTS 0), tt_points isampler2D (TT_POINTS 1).
// Output: f_index, an unsigned integer target (R8UI or R32UI).
#include "tt_packed.glsl"

#ifndef TT_POINTS
#define TT_POINTS 0
#endif

#if TT_POINTS == 1
uniform isampler2D tt_points;
#else
uniform ivec2 tt_origin;
#endif
out uint f_index;

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
#if TT_POINTS == 1
    f_index = tt_packed_index(texelFetch(tt_points, pixel, 0).rg);
#else
    f_index = min(tt_packed_index(tt_origin + pixel), 255u);
#endif
}
