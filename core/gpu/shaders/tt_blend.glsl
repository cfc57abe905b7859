// terratheme blend rule (Vyatkin & Romanyuk; docs/gpu.md), GLSL 3.30 core library.
//
// Included by tt_terrain.frag.glsl and tt_uniform.frag.glsl (an `#include`
// line; core/gpu/shaders.py expands it, as do most engines' preprocessors).
// Everything here is prefixed tt_ so it can sit beside an engine's own code.
//
// Defines (set them after the #version line):
//   TT_THEMES    number of themes K (required; grid indices are 0..K-1)
//   TT_BLEND     0 linear (the paper's weighted sum), 1 histogram-preserving
//                (Heitz & Neyret, HPG 2018); default 0
//   TT_FILTERED  0 exact: texelFetch with integer wrap, one output pixel per
//                texel, equal to the CPU renderer (core.render.render_cells);
//                1 filtered: textureGrad with mipmaps and anisotropic
//                filtering at any scale or angle (fly-over); default 0
//   TT_LUT_SIZE  entries of the inverse LUT rows (TT_BLEND 1; default 4096)
//   TT_ONE_SIZE  1 when every theme has the layer size of tt_themes: the
//                exact path then wraps with the sampler's REPEAT (cheaper than
//                integer wrapping; tt_wrap_origin keeps coordinates small);
//                default 0
//   TT_COLOUR_MAP 1 multiplies the render by a colour map (below); default 0.
//                A compile-time switch: a software rasteriser runs both sides
//                of a branch on a uniform bool, which would cost every pixel
//
// Texel convention: a texel position p is given in texels of the full
// texture with texel X's centre at p = X (so p = X/N in grid cells: the
// texel on a vertex shows that vertex's theme exactly). Row 0 is the top row
// of the index grid.
//
// Textures and uniforms:
//   tt_grid        usampler2D R8UI: theme index at every vertex of the block
//                  of the grid bound (texel (i, j) = vertex column i, row j,
//                  counted from tt_block_cell)
//   tt_splits      usampler2D R8UI: per-cell split of the same block:
//                  0 uniform, 1 main diagonal (corner 00-11), 2 anti diagonal
//                  (01-10), as core.render.rules.cell_splits decides them
//                  (saddle rule included)
//   tt_block_cell  ivec2: global cell (column, row) of tt_splits texel (0, 0)
//   tt_block_cells ivec2: cells in the bound block (filtered path clamps to it)
//   tt_cell        ivec2: (N, M) texel columns and rows per cell
//   tt_themes      sampler2DArray RGBA8: layer k = theme k. Exact path: theme
//                  k occupies texels [0, w_k) x [0, h_k) of its layer (layers
//                  padded to the largest theme), NEAREST, REPEAT (used with
//                  TT_ONE_SIZE 1). Filtered path: every
//                  layer holds its theme resampled to the layer size, REPEAT,
//                  mipmapped, anisotropic.
//   tt_theme_size  vec4[TT_THEMES]: (w_k, h_k, 1/w_k, 1/h_k), the theme's own
//                  size in texels (it repeats every w_k x h_k texels)
//   tt_wrap_origin ivec2 (TT_ONE_SIZE 1): a whole number of theme periods
//                  subtracted from texel positions before scaling them to
//                  texture coordinates (0 is exact below 2^21 texels)
//   tt_gauss       sampler2DArray RGB32F (TT_BLEND 1): the Gaussianised
//                  themes G = Phi^-1(CDF(T)), same layout as tt_themes
//   tt_inverse_lut sampler2D R32F (TT_BLEND 1): TT_LUT_SIZE x 3K; row 3k+c is
//                  theme k channel c's inverse transform tabulated for g evenly
//                  over [-tt_lut_range, tt_lut_range] (core.render.theme_pack)
//   tt_lut_range   float (TT_BLEND 1): half-range of the LUT axis (6.0)
//   tt_supersample int (filtered path): S x S sub-samples per pixel for the
//                  weights (1 for a fly-over; more for a reduced overview)
//   Colour map (TT_COLOUR_MAP 1 only):
//   tt_colour_map      sampler2D RGBA8: low-resolution colour map spanning
//                      the whole texture; value 128 is neutral; the render is
//                      multiplied per channel by value / 128, bilinear
//                      (texel centres aligned, clamped at the border), rounded
//   tt_texture_size    vec2: full texture size in texels (W, H)

#ifndef TT_BLEND
#define TT_BLEND 0
#endif
#ifndef TT_FILTERED
#define TT_FILTERED 0
#endif
#ifndef TT_LUT_SIZE
#define TT_LUT_SIZE 4096
#endif
#ifndef TT_COLOUR_MAP
#define TT_COLOUR_MAP 0
#endif
#ifndef TT_ONE_SIZE
#define TT_ONE_SIZE 0
#endif

uniform usampler2D tt_grid;
uniform usampler2D tt_splits;
uniform ivec2 tt_block_cell;
uniform ivec2 tt_block_cells;
uniform ivec2 tt_cell;
uniform sampler2DArray tt_themes;
uniform vec4 tt_theme_size[TT_THEMES];
#if TT_ONE_SIZE == 1
uniform ivec2 tt_wrap_origin;
#endif
#if TT_BLEND == 1
uniform sampler2DArray tt_gauss;
uniform sampler2D tt_inverse_lut;
uniform float tt_lut_range;
#endif
#if TT_FILTERED == 1
uniform int tt_supersample;
#endif
#if TT_COLOUR_MAP == 1
uniform sampler2D tt_colour_map;
uniform vec2 tt_texture_size;
#endif

// Fixed-point scale of local cell coordinates in the filtered path.
const int TT_FRAC = 4096;

// floor(a / b) and a - b*floor(a / b) for b > 0 and |a| < 2^23: a float
// estimate from the reciprocal, then one exact integer correction.
ivec2 tt_divmod(int a, int b, float inv_b) {
    int q = int(floor((float(a) + 0.5) * inv_b));
    int r = a - q * b;
    if (r < 0) { q -= 1; r += b; } else if (r >= b) { q += 1; r -= b; }
    return ivec2(q, r);
}

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

// The size (w, h, 1/w, 1/h) of theme k.
vec4 tt_size_of(uint k) {
#if TT_ONE_SIZE == 1
    return tt_theme_size[0];
#else
    return tt_theme_size[k];
#endif
}

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

// The linear blend rounded half up exactly: floor((2*sum(w*T) + d) / (2d)),
// for d <= 2^23 (a float estimate, one exact correction).
uvec3 tt_linear_exact(uvec3 kt, ivec3 wt, int d, ivec2 t) {
    uvec3 v = uint(wt.x) * tt_texel(kt.x, t) + uint(wt.y) * tt_texel(kt.y, t)
            + uint(wt.z) * tt_texel(kt.z, t);
    uint den = uint(2 * d);
    uvec3 num = 2u * v + uint(d);
    uvec3 q = uvec3(vec3(num) / float(den));
    q += uvec3(greaterThanEqual(num, (q + 1u) * den));
    q -= uvec3(lessThan(num, q * den));
    return q;
}

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

#if TT_COLOUR_MAP == 1
// The colour map's gain at texel position p: the map's 8-bit values, bilinear
// (texel centres aligned, clamped at the border), over 128.
vec3 tt_colour_value(ivec2 i) {
    return floor(texelFetch(tt_colour_map, i, 0).rgb * 255.0 + 0.5);
}
vec3 tt_colour_gain(vec2 p) {
    ivec2 size = textureSize(tt_colour_map, 0);
    vec2 q = (p + 0.5) * vec2(size) / tt_texture_size - 0.5;
    ivec2 i = ivec2(floor(q));
    vec2 f = q - vec2(i);
    ivec2 i0 = clamp(i, ivec2(0), size - 1);
    ivec2 i1 = clamp(i + 1, ivec2(0), size - 1);
    vec3 top = mix(tt_colour_value(i0), tt_colour_value(ivec2(i1.x, i0.y)), f.x);
    vec3 bottom = mix(tt_colour_value(ivec2(i0.x, i1.y)), tt_colour_value(i1), f.x);
    return mix(top, bottom, f.y) / 128.0;
}
#endif

// The final colour of an exact texel: the colour map applied and rounded.
vec4 tt_output_exact(uvec3 rgb, ivec2 t) {
    vec3 v = vec3(rgb);
#if TT_COLOUR_MAP == 1
    v = min(floor(v * tt_colour_gain(vec2(t)) + 0.5), 255.0);
#endif
    return vec4(v / 255.0, 1.0);
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
#else
    return tt_output_exact(tt_linear_exact(kt, wt, d, t), t);
#endif
}

// ---------------------------------------------------------------- filtered path

#if TT_FILTERED == 1
// Theme k at texel position p, filtered over the footprint (dx, dy) in texels.
vec3 tt_sample(uint k, vec2 p, vec2 dx, vec2 dy) {
    vec4 s = tt_size_of(k);
    return textureGrad(tt_themes, vec3((p + 0.5) * s.zw, float(k)), dx * s.zw, dy * s.zw).rgb;
}
#if TT_BLEND == 1
vec3 tt_sample_gauss(uint k, vec2 p, vec2 dx, vec2 dy) {
    vec4 s = tt_size_of(k);
    return textureGrad(tt_gauss, vec3((p + 0.5) * s.zw, float(k)), dx * s.zw, dy * s.zw).rgb;
}
#endif

// The blend at texel position p (0..1 per channel), footprint (dx, dy).
vec3 tt_shade_point(vec2 p, vec2 dx, vec2 dy) {
    // Step 1: the cell under p (clamped to the bound block) and the local position.
    vec2 g = p / vec2(tt_cell);
    ivec2 c = ivec2(floor(g));
    vec2 f = g - vec2(c);
    ivec2 cl = clamp(c - tt_block_cell, ivec2(0), tt_block_cells - 1);
    f = clamp(f + vec2(c - tt_block_cell - cl), 0.0, 1.0);
    ivec2 fi = ivec2(floor(f * float(TT_FRAC) + 0.5));
    // Step 2: the triangle, weights in fixed point.
    uvec3 kt;
    ivec3 wt;
    tt_triangle(tt_split_at(cl), tt_corners_at(cl), fi.x, fi.y, TT_FRAC, kt, wt);
#if TT_BLEND == 1
    // Step 3: histogram-preserving blend of the filtered Gaussianised themes.
    tt_merge_equal(kt, wt);
    if (wt.x == TT_FRAC) return tt_sample(kt.x, p, dx, dy);
    if (wt.y == TT_FRAC) return tt_sample(kt.y, p, dx, dy);
    vec3 w = vec3(wt) / float(TT_FRAC);
    vec3 gs = (w.x * tt_sample_gauss(kt.x, p, dx, dy) + w.y * tt_sample_gauss(kt.y, p, dx, dy)
             + w.z * tt_sample_gauss(kt.z, p, dx, dy)) / sqrt(dot(w, w));
    return (w.x * tt_inverse(kt.x, gs) + w.y * tt_inverse(kt.y, gs) + w.z * tt_inverse(kt.z, gs))
           / 255.0;
#else
    // Step 3: linear blend of the filtered themes.
    vec3 w = vec3(wt) / float(TT_FRAC);
    return w.x * tt_sample(kt.x, p, dx, dy) + w.y * tt_sample(kt.y, p, dx, dy)
         + w.z * tt_sample(kt.z, p, dx, dy);
#endif
}

// The pixel whose centre is at texel position p: S x S sub-samples of its
// footprint (from the screen derivatives of p), then the colour map.
vec4 tt_shade_filtered(vec2 p) {
    vec2 dx = dFdx(p);
    vec2 dy = dFdy(p);
    float inv = 1.0 / float(tt_supersample);
    vec3 acc = vec3(0.0);
    for (int j = 0; j < tt_supersample; ++j) {
        for (int i = 0; i < tt_supersample; ++i) {
            vec2 o = (vec2(i, j) + 0.5) * inv - 0.5;
            acc += tt_shade_point(p + o.x * dx + o.y * dy, dx * inv, dy * inv);
        }
    }
    vec3 rgb = acc * (inv * inv);
#if TT_COLOUR_MAP == 1
    rgb = min(rgb * tt_colour_gain(p), 1.0);
#endif
    return vec4(rgb, 1.0);
}
#endif

// The terrain colour at texel position p: the entry point an engine calls.
vec4 tt_shade(vec2 p) {
#if TT_FILTERED == 1
    return tt_shade_filtered(p);
#else
    return tt_shade_exact(ivec2(floor(p + 0.5)));
#endif
}
