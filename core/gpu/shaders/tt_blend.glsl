// terratheme blend rule (Vyatkin & Romanyuk; docs/gpu.md), GLSL 3.30 core library.
//
// Included by tt_terrain.frag.glsl and tt_ground.frag.glsl
// (an `#include` line; core/gpu/shaders.py expands it, as do most engines'
// preprocessors). It includes tt_integer.glsl, tt_border.glsl (TT_SHAPED 1)
// and tt_colour.glsl (TT_COLOUR_MAP 1). Every name is prefixed tt_.
//
// Defines (set them after the #version line):
//   TT_THEMES     number of themes K (required; grid indices are 0..K-1)
//   TT_BLEND      0 linear (the paper's weighted sum), 1 histogram-preserving
//                 (Heitz & Neyret, HPG 2018); default 0
//   TT_SHAPED     1: borders shaped by the themes and noise (tt_border.glsl,
//                 linear blend only); default 0
//   TT_FILTERED   0 exact: texelFetch with integer wrap, one output pixel per
//                 texel, equal to the CPU renderer (core.render.render_cells);
//                 1 filtered: mipmaps and anisotropic filtering at any scale or
//                 angle (overviews, the fly-over); default 0
//   TT_WRAP       1 (filtered path): the texture repeats beyond its edges (a
//                 ground plane); 0 clamps to the bound block; default 0
//   TT_LUT_SIZE   entries of the inverse LUT rows (TT_BLEND 1; default 4096)
//   TT_ONE_SIZE   1 when every theme has the layer size of tt_themes: the
//                 exact path wraps with the sampler's REPEAT; default 0
//   TT_BOX        filtered path, axis-aligned footprints (flat renders): each
//                 theme's mean over the footprint from its summed-area table
//                 (tt_box) instead of mipmaps; 1 footprints at most a theme
//                 wide, 2 any; default 0
//   TT_COLOUR_MAP 1 multiplies the render by a colour map (tt_colour.glsl);
//                 default 0. Compile-time switches, not uniform bools: a
//                 software rasteriser runs both sides of a branch on a uniform
//
// Texel convention: a texel position p is given in texels of the full
// texture with texel X's centre at p = X (so p = X/N in grid cells: the
// texel on a vertex shows that vertex's theme exactly). Row 0 is the top row
// of the index grid.
//
// Textures and uniforms:
//   tt_grid        usampler2D R8UI: theme index at every vertex of the bound
//                  block (texel (i, j) = vertex column i, row j from tt_block_cell)
//   tt_splits      usampler2D R8UI: per-cell split of the same block: 0 uniform,
//                  1 main diagonal (corner 00-11), 2 anti diagonal (01-10), as
//                  core.render.rules.cell_splits decides them (saddle rule included)
//   tt_block_cell  ivec2: global cell (column, row) of tt_splits texel (0, 0)
//   tt_block_cells ivec2: cells in the bound block (the filtered path clamps to it)
//   tt_cell        ivec2: (N, M) texel columns and rows per cell
//   tt_themes      sampler2DArray RGBA8: layer k = theme k. Exact path: theme k
//                  in texels [0, w_k) x [0, h_k) of its layer (layers padded to
//                  the largest), NEAREST, REPEAT (used with TT_ONE_SIZE 1).
//                  Filtered path: every layer holds its theme resampled to the
//                  layer size, REPEAT, mipmapped, anisotropic.
//   tt_box         usampler2DArray RGB32UI (TT_BOX > 0): layer k = the sums of theme
//                  k tiled 2 x 2 above and left of each texel corner, (2h_k+1) x
//                  (2w_k+1) in the corner of its layer, modulo 2^32
//   tt_theme_size  vec4[TT_THEMES]: (w_k, h_k, 1/w_k, 1/h_k), the theme's own size
//   tt_wrap_origin ivec2 (TT_ONE_SIZE 1): a whole number of theme periods
//                  subtracted before scaling to texture coordinates
//   tt_texture_size vec2: the full texture's size (W, H) in texels
//   tt_gauss       sampler2DArray RGB32F (TT_BLEND 1): Gaussianised themes
//                  G = Phi^-1(CDF(T)), same layout as tt_themes
//   tt_inverse_lut sampler2D R32F (TT_BLEND 1): TT_LUT_SIZE x 3K; row 3k+c is
//                  theme k channel c's inverse transform over
//                  [-tt_lut_range, tt_lut_range] (core.render.theme_pack)
//   tt_lut_range   float (TT_BLEND 1): half-range of the LUT axis (6.0)
//   tt_max_supersample int (filtered path): most weight sub-samples per pixel side
//   tt_border, tt_border_seed (TT_SHAPED 1): tt_border.glsl
//   tt_colour_map, tt_colour_scale (TT_COLOUR_MAP 1): tt_colour.glsl

#ifndef TT_BLEND
#define TT_BLEND 0
#endif
#ifndef TT_SHAPED
#define TT_SHAPED 0
#endif
#ifndef TT_FILTERED
#define TT_FILTERED 0
#endif
#ifndef TT_WRAP
#define TT_WRAP 0
#endif
#ifndef TT_LUT_SIZE
#define TT_LUT_SIZE 4096
#endif
#ifndef TT_COLOUR_MAP
#define TT_COLOUR_MAP 0
#endif
#ifndef TT_BOX
#define TT_BOX 0
#endif
#ifndef TT_ONE_SIZE
#define TT_ONE_SIZE 0
#endif

#include "tt_integer.glsl"
#if TT_SHAPED == 1
#include "tt_border.glsl"
#endif
#if TT_COLOUR_MAP == 1
#include "tt_colour.glsl"
#endif

uniform usampler2D tt_grid;
uniform usampler2D tt_splits;
uniform ivec2 tt_block_cell;
uniform ivec2 tt_block_cells;
uniform ivec2 tt_cell;
uniform sampler2DArray tt_themes;
uniform vec4 tt_theme_size[TT_THEMES];
uniform vec2 tt_texture_size;
#if TT_ONE_SIZE == 1
uniform ivec2 tt_wrap_origin;
#endif
#if TT_BLEND == 1
uniform sampler2DArray tt_gauss;
uniform sampler2D tt_inverse_lut;
uniform float tt_lut_range;
#endif
#if TT_FILTERED == 1
uniform int tt_max_supersample;
#endif
#if TT_BOX > 0
uniform usampler2DArray tt_box;
#endif

// Fixed-point scale of local cell coordinates in the filtered path.
const int TT_FRAC = 4096;

// The split and the four corner themes (00, 01, 10, 11) of a cell of the block.
int tt_split_at(ivec2 c) {
    return int(texelFetch(tt_splits, c, 0).r);
}
uvec4 tt_corners_at(ivec2 c) {
    return uvec4(texelFetch(tt_grid, c, 0).r, texelFetch(tt_grid, c + ivec2(1, 0), 0).r,
                 texelFetch(tt_grid, c + ivec2(0, 1), 0).r, texelFetch(tt_grid, c + ivec2(1, 1), 0).r);
}

// The triangle holding local point (xi, yi) (cell coordinates times d, in
// [0, d]): its three corner themes kt and integer barycentric weights wt
// (sum d), as core.render.rules.corner_weights. A uniform cell puts d on 00.
void tt_triangle(int split, uvec4 k, int xi, int yi, int d, out uvec3 kt, out ivec3 wt) {
    if (split == 1) {
        // Main diagonal: T00*(1-y) + T11*x + T10*(y-x) below it, T01*(x-y) above.
        kt.xy = k.xw;
        if (xi <= yi) { kt.z = k.z; wt = ivec3(d - yi, xi, yi - xi); }
        else          { kt.z = k.y; wt = ivec3(d - xi, yi, xi - yi); }
    } else if (split == 2) {
        // Anti diagonal: T01*x + T10*y + T00*(1-x-y) before it, T11*(x+y-1) beyond.
        kt.xy = k.yz;
        if (xi + yi <= d) { kt.z = k.x; wt = ivec3(xi, yi, d - xi - yi); }
        else              { kt.z = k.w; wt = ivec3(d - yi, d - xi, xi + yi - d); }
    } else {
        kt = k.xxx;
        wt = ivec3(d, 0, 0);
    }
}

// Corners carrying the same theme add their weights (identical samples).
void tt_merge_equal(uvec3 kt, inout ivec3 wt) {
    if (kt.y == kt.x) { wt.x += wt.y; wt.y = 0; }
    if (kt.z == kt.x) { wt.x += wt.z; wt.z = 0; }
    else if (kt.z == kt.y) { wt.y += wt.z; wt.z = 0; }
}

#if TT_BLEND == 1
// Theme k's inverse Gaussianisation of g, per channel, linear between LUT entries.
vec3 tt_inverse(uint k, vec3 g) {
    float last = float(TT_LUT_SIZE - 1);
    vec3 pos = clamp((g + tt_lut_range) * (last / (2.0 * tt_lut_range)), 0.0, last);
    ivec3 i = min(ivec3(pos), ivec3(TT_LUT_SIZE - 2));
    vec3 f = pos - vec3(i);
    int row = 3 * int(k);
    vec3 lo = vec3(texelFetch(tt_inverse_lut, ivec2(i.x, row), 0).r,
                   texelFetch(tt_inverse_lut, ivec2(i.y, row + 1), 0).r,
                   texelFetch(tt_inverse_lut, ivec2(i.z, row + 2), 0).r);
    vec3 hi = vec3(texelFetch(tt_inverse_lut, ivec2(i.x + 1, row), 0).r,
                   texelFetch(tt_inverse_lut, ivec2(i.y + 1, row + 1), 0).r,
                   texelFetch(tt_inverse_lut, ivec2(i.z + 1, row + 2), 0).r);
    return mix(lo, hi, f);
}
#endif

// ---------------------------------------------------------------- exact path

#if TT_ONE_SIZE == 1
// Texture coordinate of global texel t in a layer: the sampler's REPEAT wraps it.
vec3 tt_layer_coord(uint k, ivec2 t) {
    return vec3((vec2(t - tt_wrap_origin) + 0.5) * tt_theme_size[0].zw, float(k));
}
#else
// Theme k's texel at global texel t, wrapping with the theme's own size.
ivec3 tt_wrapped(uint k, ivec2 t) {
    vec4 size = tt_theme_size[k];
    return ivec3(tt_divmod(t.x, int(size.x), size.z).y, tt_divmod(t.y, int(size.y), size.w).y, int(k));
}
#endif

uvec3 tt_texel(uint k, ivec2 t) {
#if TT_ONE_SIZE == 1
    vec4 c = texture(tt_themes, tt_layer_coord(k, t));
#else
    vec4 c = texelFetch(tt_themes, tt_wrapped(k, t), 0);
#endif
    return uvec3(c.rgb * 255.0 + 0.5);
}

#if TT_BLEND == 1
vec3 tt_gauss_at(uint k, ivec2 t) {
#if TT_ONE_SIZE == 1
    return texture(tt_gauss, tt_layer_coord(k, t)).rgb;
#else
    return texelFetch(tt_gauss, tt_wrapped(k, t), 0).rgb;
#endif
}
#endif

// The blend sum(w * T) / d of three 8-bit texels rounded half up exactly:
// floor((2 * sum + d) / (2d)), for d <= 2^23.
uvec3 tt_round_blend(uvec3 a, uvec3 b, uvec3 c, ivec3 w, int d) {
    uvec3 num = 2u * (uint(w.x) * a + uint(w.y) * b + uint(w.z) * c) + uint(d);
    return tt_quotient3(num, uint(2 * d), vec3(num) / float(2 * d));
}

// The paper's linear blend at texel t.
uvec3 tt_linear_exact(uvec3 kt, ivec3 wt, int d, ivec2 t) {
    return tt_round_blend(tt_texel(kt.x, t), tt_texel(kt.y, t), tt_texel(kt.z, t), wt, d);
}

#if TT_SHAPED == 1
// The shaped-boundary blend at texel t (core.render.boundary.shaped_rows):
// sum(v * T) / sum(v) rounded half up, v the border weights.
uvec3 tt_shaped_exact(uvec3 kt, ivec3 wt, int d, ivec2 t) {
    tt_merge_equal(kt, wt);
    uvec3 a = tt_texel(kt.x, t), b = tt_texel(kt.y, t), c = tt_texel(kt.z, t);
    ivec3 v = tt_border_weights(kt, wt, d, t, ivec3(tt_luma(a), tt_luma(b), tt_luma(c)));
    return tt_round_blend(a, b, c, v, v.x + v.y + v.z);
}
#endif

#if TT_BLEND == 1
// Histogram-preserving blend at texel t (core.render.kernels.histogram_rows):
// g = sum(w G) / sqrt(sum(w^2)), out = sum(w Q(g)) / d rounded; a theme at full
// weight is its texel exactly.
uvec3 tt_histogram_exact(uvec3 kt, ivec3 wt, int d, ivec2 t) {
    tt_merge_equal(kt, wt);
    if (wt.x == d) return tt_texel(kt.x, t);
    if (wt.y == d) return tt_texel(kt.y, t);
    vec3 w = vec3(wt);
    vec3 g = w.x * tt_gauss_at(kt.x, t) + w.y * tt_gauss_at(kt.y, t) + w.z * tt_gauss_at(kt.z, t);
    g /= sqrt(dot(w, w));
    vec3 v = w.x * tt_inverse(kt.x, g) + w.y * tt_inverse(kt.y, g) + w.z * tt_inverse(kt.z, g);
    return uvec3(clamp(ivec3(v / float(d) + 0.5), 0, 255));
}
#endif

// The final colour of an exact texel: the colour map applied (exact integers).
vec4 tt_output_exact(uvec3 rgb, ivec2 t) {
#if TT_COLOUR_MAP == 1
    rgb = tt_colour_exact(rgb, t);
#endif
    return vec4(vec3(rgb) / 255.0, 1.0);
}

// The blended texel t (global integer texel), equal to the CPU renderer.
vec4 tt_shade_exact(ivec2 t) {
    // Step 1: the cell of the block and the texel's place in it.
    ivec2 cx = tt_divmod(t.x, tt_cell.x, 1.0 / float(tt_cell.x));
    ivec2 cy = tt_divmod(t.y, tt_cell.y, 1.0 / float(tt_cell.y));
    ivec2 c = ivec2(cx.x, cy.x) - tt_block_cell;
    int d = tt_cell.x * tt_cell.y;
    // Step 2: the triangle and its integer weights (local coordinates times d).
    uvec3 kt;
    ivec3 wt;
    tt_triangle(tt_split_at(c), tt_corners_at(c), cx.y * tt_cell.y, cy.y * tt_cell.x, d, kt, wt);
    // Step 3: the blend.
#if TT_BLEND == 1
    return tt_output_exact(tt_histogram_exact(kt, wt, d, t), t);
#elif TT_SHAPED == 1
    return tt_output_exact(tt_shaped_exact(kt, wt, d, t), t);
#else
    return tt_output_exact(tt_linear_exact(kt, wt, d, t), t);
#endif
}

#if TT_FILTERED == 1
#include "tt_filtered.glsl"
#endif

// The terrain colour at texel position p: the entry point an engine calls.
vec4 tt_shade(vec2 p) {
#if TT_FILTERED == 1
    return tt_shade_footprint(p, dFdx(p), dFdy(p));
#else
    return tt_shade_exact(ivec2(floor(p + 0.5)));
#endif
}
