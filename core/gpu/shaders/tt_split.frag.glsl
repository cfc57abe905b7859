#version 330 core
// terratheme cell splits on the GPU from a packed layer (docs/gpu.md "Packed
// layers"): core.render.rules.cell_splits per fragment, so that the blend
// shader's tt_splits never comes from an unpacked grid.
//
// Fragment (i, j) is cell tt_origin + (i, j). Its four corners come from
// tt_grid (the block tt_unpack.frag.glsl decoded, vertex tt_origin at texel
// (0, 0)); a saddle's ring of 12 vertices from the packed layer itself
// (vertices outside the grid are not counted, as on the CPU).
// Defines: TT_MINORITY 1 (SaddleRule.MINORITY: the theme with fewer ring
// vertices connects, tie the lower index) or 0 (SaddleRule.MAIN).
// Output: f_split, R8UI: 0 uniform, 1 main diagonal, 2 anti diagonal.
#include "tt_packed.glsl"

#ifndef TT_MINORITY
#define TT_MINORITY 1
#endif

uniform usampler2D tt_grid;
uniform ivec2 tt_origin;
out uint f_split;

void main() {
    ivec2 c = ivec2(gl_FragCoord.xy);
    // Step 1: the corners 00, 01 (right), 10 (below), 11.
    uint a = texelFetch(tt_grid, c, 0).r, b = texelFetch(tt_grid, c + ivec2(1, 0), 0).r;
    uint l = texelFetch(tt_grid, c + ivec2(0, 1), 0).r, d = texelFetch(tt_grid, c + ivec2(1, 1), 0).r;
    bool main_eq = a == d, anti_eq = b == l;
    // Step 2: the equal-ended diagonal; three or four themes split along the main one.
    uint split = (anti_eq && !main_eq) ? 2u : 1u;
    if (main_eq && anti_eq && a == b) split = 0u;
#if TT_MINORITY == 1
    // Step 3: a saddle connects the theme with fewer vertices in the ring.
    if (main_eq && anti_eq && a != b) {
        ivec2 v = tt_origin + c;
        int ca = 0, cb = 0;
        for (int dy = -1; dy <= 2; ++dy) {
            for (int dx = -1; dx <= 2; ++dx) {
                if ((dy == 0 || dy == 1) && (dx == 0 || dx == 1)) continue;
                uint k = tt_packed_index(v + ivec2(dx, dy));
                ca += int(k == a);
                cb += int(k == b);
            }
        }
        if (cb < ca || (cb == ca && b < a)) split = 2u;
    }
#endif
    f_split = split;
}
