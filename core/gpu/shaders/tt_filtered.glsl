// terratheme filtered path (docs/gpu.md): the blend rule at any scale or angle, GLSL 3.30.
//
// Included by tt_blend.glsl when TT_FILTERED is 1 (its uniforms are listed
// there). A pixel's footprint is the parallelogram spanned by dx and dy (the
// texel steps of one pixel step along the screen axes: dFdx and dFdy of the
// texel position, or eq. 2 of a ground plane). The weights change at the cell
// scale, so they are sub-sampled over the footprint (two sub-samples per cell
// it spans along each side, at most tt_max_supersample); the themes carry the
// fine detail, so each distinct theme under the footprint is read once, over
// the whole footprint: with mipmaps and anisotropic filtering, or (TT_BOX,
// flat renders) as its exact mean over the footprint's box from its
// summed-area table, which mipmaps of themes of any size cannot give. The colour is
// sum(mean weight of theme t * filtered theme t): the linear blend, the shaped
// borders' weights (TT_SHAPED 1: the theme's luminance from its filtered
// read, the noise at the sub-sample's texel) or the histogram-preserving blend
// of the filtered Gaussianised themes (TT_BLEND 1). At one texel per pixel
// this is the exact render within a level or two (weights in 1/4096).

// Distinct themes one footprint can blend (the rest are dropped, weights renormalised).
const int TT_SLOTS = 4;

#ifndef TT_PROBES
#define TT_PROBES 0
#endif

#if TT_PROBES > 1
// Anisotropic filtering in the shader (TT_PROBES, for drivers whose own is slow): up to
// TT_PROBES trilinear reads spaced along the footprint's longer side, each at the level of
// the longer side over the probe count (or of the shorter side, if longer), averaged.
// Returns the probe count n, the level, and the step between probes in texture
// units; size is the texture's level 0 in texels.
int tt_probes(vec2 dx, vec2 dy, vec2 size, out float lod, out vec2 step) {
    float lx = dot(dx * size, dx * size), ly = dot(dy * size, dy * size);
    float big = sqrt(max(lx, ly)), small = sqrt(min(lx, ly));
    int n = int(clamp(ceil(big / max(small, 1e-6 * big) - 1e-3), 1.0, float(TT_PROBES)));
    lod = log2(max(max(small, big / float(n)), 1e-8));
    step = (lx > ly ? dx : dy) / float(n);
    return n;
}
vec3 tt_probe(sampler2DArray tex, vec3 at, vec2 dx, vec2 dy) {
    float lod;
    vec2 step;
    int n = tt_probes(dx, dy, vec2(textureSize(tex, 0).xy), lod, step);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < n; ++i) {
        sum += textureLod(tex, vec3(at.xy + (float(i) - 0.5 * float(n - 1)) * step, at.z), lod).rgb;
    }
    return sum / float(n);
}
vec3 tt_probe(sampler2D tex, vec2 at, vec2 dx, vec2 dy) {
    float lod;
    vec2 step;
    int n = tt_probes(dx, dy, vec2(textureSize(tex, 0)), lod, step);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < n; ++i) {
        sum += textureLod(tex, at + (float(i) - 0.5 * float(n - 1)) * step, lod).rgb;
    }
    return sum / float(n);
}
#endif

#if TT_COLOUR_MAP == 1
// The colour map's gain (value / 128) at texel position p over the footprint (dx, dy).
vec3 tt_colour_filtered(vec2 p, vec2 dx, vec2 dy) {
    vec2 span = float(tt_colour_scale) * vec2(textureSize(tt_colour_map, 0));
#if TT_PROBES > 1
    vec3 value = tt_probe(tt_colour_map, (p + 0.5) / span, dx / span, dy / span);
#else
    vec3 value = textureGrad(tt_colour_map, (p + 0.5) / span, dx / span, dy / span).rgb;
#endif
    return value * (255.0 / 128.0);
}
#endif

// Layer k of a theme array (tt_themes or tt_gauss) at texel position p, filtered over
// the footprint (dx, dy) in texels.
vec3 tt_sample_layer(sampler2DArray tex, uint k, vec2 p, vec2 dx, vec2 dy) {
    vec4 s = tt_theme_size[k];
#if TT_PROBES > 1
    return tt_probe(tex, vec3((p + 0.5) * s.zw, float(k)), dx * s.zw, dy * s.zw);
#else
    return textureGrad(tex, vec3((p + 0.5) * s.zw, float(k)), dx * s.zw, dy * s.zw).rgb;
#endif
}
#if TT_BOX > 0
// Integral of layer k's texels over [lo, hi) (texels; lo in the first period, hi - lo at
// most one period): the summed-area table at the box's fractional corners (bilinear in
// the table is exact for square texels), as the 16 integer boxes between the corners'
// neighbouring texel edges, each exact (signed: the table's uint wraps, int keeps it),
// weighted in float. Sixteen reads, no arrays (llvmpipe spills those to memory).
vec3 tt_box_integral(int k, vec2 lo, vec2 hi, ivec2 last) {
    ivec2 i0 = min(ivec2(floor(lo)), last), i1 = min(ivec2(floor(hi)), last);
    vec2 f0 = clamp(lo - vec2(i0), 0.0, 1.0), f1 = clamp(hi - vec2(i1), 0.0, 1.0);
    ivec4 x = min(ivec4(i0.x, i0.x + 1, i1.x, i1.x + 1), last.x);
    ivec4 y = min(ivec4(i0.y, i0.y + 1, i1.y, i1.y + 1), last.y);
    // Weights of the (from, to) edge pairs along each axis, in the order used below.
    vec4 wx = vec4((1.0 - f0.x) * (1.0 - f1.x), (1.0 - f0.x) * f1.x,
                   f0.x * (1.0 - f1.x), f0.x * f1.x);
    vec4 wy = vec4((1.0 - f0.y) * (1.0 - f1.y), (1.0 - f0.y) * f1.y,
                   f0.y * (1.0 - f1.y), f0.y * f1.y);
    uvec3 a0 = texelFetch(tt_box, ivec3(x.x, y.x, k), 0).rgb;
    uvec3 b0 = texelFetch(tt_box, ivec3(x.y, y.x, k), 0).rgb;
    uvec3 c0 = texelFetch(tt_box, ivec3(x.z, y.x, k), 0).rgb;
    uvec3 d0 = texelFetch(tt_box, ivec3(x.w, y.x, k), 0).rgb;
    uvec3 a1 = texelFetch(tt_box, ivec3(x.x, y.y, k), 0).rgb;
    uvec3 b1 = texelFetch(tt_box, ivec3(x.y, y.y, k), 0).rgb;
    uvec3 c1 = texelFetch(tt_box, ivec3(x.z, y.y, k), 0).rgb;
    uvec3 d1 = texelFetch(tt_box, ivec3(x.w, y.y, k), 0).rgb;
    uvec3 a2 = texelFetch(tt_box, ivec3(x.x, y.z, k), 0).rgb;
    uvec3 b2 = texelFetch(tt_box, ivec3(x.y, y.z, k), 0).rgb;
    uvec3 c2 = texelFetch(tt_box, ivec3(x.z, y.z, k), 0).rgb;
    uvec3 d2 = texelFetch(tt_box, ivec3(x.w, y.z, k), 0).rgb;
    uvec3 a3 = texelFetch(tt_box, ivec3(x.x, y.w, k), 0).rgb;
    uvec3 b3 = texelFetch(tt_box, ivec3(x.y, y.w, k), 0).rgb;
    uvec3 c3 = texelFetch(tt_box, ivec3(x.z, y.w, k), 0).rgb;
    uvec3 d3 = texelFetch(tt_box, ivec3(x.w, y.w, k), 0).rgb;
    // Row differences: columns (from, to) = (x.x, x.z), (x.x, x.w), (x.y, x.z), (x.y, x.w).
    uvec3 p00 = c0 - a0, p01 = d0 - a0, p10 = c0 - b0, p11 = d0 - b0;
    uvec3 q00 = c1 - a1, q01 = d1 - a1, q10 = c1 - b1, q11 = d1 - b1;
    uvec3 s00 = c2 - a2, s01 = d2 - a2, s10 = c2 - b2, s11 = d2 - b2;
    uvec3 t00 = c3 - a3, t01 = d3 - a3, t10 = c3 - b3, t11 = d3 - b3;
    // Boxes between rows (from, to) = (y.x, y.z), (y.x, y.w), (y.y, y.z), (y.y, y.w).
    vec3 e0 = wx.x * vec3(ivec3(s00 - p00)) + wx.y * vec3(ivec3(s01 - p01))
            + wx.z * vec3(ivec3(s10 - p10)) + wx.w * vec3(ivec3(s11 - p11));
    vec3 e1 = wx.x * vec3(ivec3(t00 - p00)) + wx.y * vec3(ivec3(t01 - p01))
            + wx.z * vec3(ivec3(t10 - p10)) + wx.w * vec3(ivec3(t11 - p11));
    vec3 e2 = wx.x * vec3(ivec3(s00 - q00)) + wx.y * vec3(ivec3(s01 - q01))
            + wx.z * vec3(ivec3(s10 - q10)) + wx.w * vec3(ivec3(s11 - q11));
    vec3 e3 = wx.x * vec3(ivec3(t00 - q00)) + wx.y * vec3(ivec3(t01 - q01))
            + wx.z * vec3(ivec3(t10 - q10)) + wx.w * vec3(ivec3(t11 - q11));
    return wy.x * e0 + wy.y * e1 + wy.z * e2 + wy.w * e3;
}

// Theme k's mean over the box of `size` texels (at least 1) centred on texel position p.
// TT_BOX 2 (a footprint wider than a theme): its whole periods from the period's sum, the
// rest from tt_box_integral; TT_BOX 1: one integral, the box at most one period (as the
// renderer chooses: the branches cost on a software rasteriser even when not taken).
vec3 tt_box_mean(uint k, vec2 p, vec2 size) {
    vec4 s = tt_theme_size[k];
    vec2 span = max(size, vec2(1.0));
#if TT_BOX == 2
    vec2 periods = floor(span * s.zw);
#else
    span = min(span, s.xy);
    vec2 periods = vec2(0.0);
#endif
    vec2 rest = span - periods * s.xy;
    vec2 lo = p + 0.5 - 0.5 * span;
    lo -= floor(lo * s.zw) * s.xy;
    lo += s.xy * (vec2(lessThan(lo, vec2(0.0))) - vec2(greaterThanEqual(lo, s.xy)));
    ivec2 last = 2 * ivec2(s.xy);
    int layer = int(k);
    vec3 sum = tt_box_integral(layer, lo, lo + rest, last);
#if TT_BOX == 2
    sum += periods.x * tt_box_integral(layer, vec2(0.0, lo.y), vec2(s.x, lo.y + rest.y), last);
    sum += periods.y * tt_box_integral(layer, vec2(lo.x, 0.0), vec2(lo.x + rest.x, s.y), last);
    sum += periods.x * periods.y * tt_box_integral(layer, vec2(0.0), s.xy, last);
#endif
    return sum / (255.0 * span.x * span.y);
}
#endif

// Theme k at texel position p, filtered over the footprint (dx, dy) in texels: with
// TT_BOX its exact mean over the footprint's bounding box, else mipmapped.
vec3 tt_sample(uint k, vec2 p, vec2 dx, vec2 dy) {
#if TT_BOX > 0
    return tt_box_mean(k, p, abs(dx) + abs(dy));
#else
    return tt_sample_layer(tt_themes, k, p, dx, dy);
#endif
}
#if TT_BLEND == 1
vec3 tt_sample_gauss(uint k, vec2 p, vec2 dx, vec2 dy) {
    return tt_sample_layer(tt_gauss, k, p, dx, dy);
}
#endif

// A texel position inside the texture: wrapped (TT_WRAP 1), else as given.
vec2 tt_place(vec2 p) {
#if TT_WRAP == 1
    return p - floor(p / tt_texture_size) * tt_texture_size;
#else
    return p;
#endif
}

// Sub-samples along one footprint side: two per cell it spans, 1..tt_max_supersample.
int tt_steps(vec2 side) {
    vec2 cells = abs(side) / vec2(tt_cell);
    return int(clamp(ceil(2.0 * max(cells.x, cells.y) - 1e-4), 1.0, float(tt_max_supersample)));
}

// The triangle at point p (clamped to the bound block): themes and weights in TT_FRAC.
void tt_triangle_at(vec2 p, out uvec3 kt, out ivec3 wt) {
    vec2 g = p / vec2(tt_cell);
    ivec2 c = ivec2(floor(g));
    vec2 f = g - vec2(c);
    ivec2 cl = clamp(c - tt_block_cell, ivec2(0), tt_block_cells - 1);
    f = clamp(f + vec2(c - tt_block_cell - cl), 0.0, 1.0);
    ivec2 fi = ivec2(floor(f * float(TT_FRAC) + 0.5));
    tt_triangle(tt_split_at(cl), tt_corners_at(cl), fi.x, fi.y, TT_FRAC, kt, wt);
    tt_merge_equal(kt, wt);
}

// The slot holding theme k (0..3), or -1.
int tt_slot_of(uvec4 themes, uint k) {
    return k == themes.x ? 0 : k == themes.y ? 1 : k == themes.z ? 2 : k == themes.w ? 3 : -1;
}

// One-hot vector of slot s (zero for -1).
vec4 tt_slot_mask(int s) {
    return vec4(equal(ivec4(s), ivec4(0, 1, 2, 3)));
}

// The pixel whose centre is at texel position p, footprint (dx, dy): RGBA in [0, 1].
// The slots are vectors and unrolled selections, not arrays: a software
// rasteriser keeps dynamically indexed arrays in memory, several times slower.
vec4 tt_shade_footprint(vec2 p, vec2 dx, vec2 dy) {
    vec2 centre = tt_place(p);
    int sx = tt_steps(dx);
    int sy = tt_steps(dy);
    uvec4 themes = uvec4(0xFFFFFFFFu);
    vec4 weight = vec4(0.0);
    vec3 c0 = vec3(0.0), c1 = vec3(0.0), c2 = vec3(0.0), c3 = vec3(0.0);
#if TT_SHAPED == 1
    ivec4 luma = ivec4(0);
    ivec2 last = ivec2(tt_texture_size) - 1;
#endif
#if TT_BLEND == 1
    vec3 g0 = vec3(0.0), g1 = vec3(0.0), g2 = vec3(0.0), g3 = vec3(0.0);
#endif
    int used = 0;
    for (int j = 0; j < sy; ++j) {
        for (int i = 0; i < sx; ++i) {
            // Step 1: the sub-sample's triangle and weights.
            vec2 o = (vec2(i, j) + 0.5) / vec2(sx, sy) - 0.5;
            vec2 q = tt_place(p + o.x * dx + o.y * dy);
            uvec3 kt;
            ivec3 wt;
            tt_triangle_at(q, kt, wt);
            // Step 2: each theme of non-zero weight in a slot, read once when it first appears.
            ivec3 slot = ivec3(-1);
            for (int c = 0; c < 3; ++c) {
                if (wt[c] == 0) continue;
                int s = tt_slot_of(themes, kt[c]);
                if (s < 0 && used < TT_SLOTS) {
                    vec3 colour = tt_sample(kt[c], centre, dx, dy);
#if TT_BLEND == 1
                    vec3 gauss = tt_sample_gauss(kt[c], centre, dx, dy);
#endif
                    s = used++;
                    if (s == 0) { themes.x = kt[c]; c0 = colour; }
                    else if (s == 1) { themes.y = kt[c]; c1 = colour; }
                    else if (s == 2) { themes.z = kt[c]; c2 = colour; }
                    else { themes.w = kt[c]; c3 = colour; }
#if TT_SHAPED == 1
                    luma = ivec4(mix(vec4(luma), vec4(tt_luma(uvec3(colour * 255.0 + 0.5))),
                                     tt_slot_mask(s)));
#endif
#if TT_BLEND == 1
                    if (s == 0) g0 = gauss; else if (s == 1) g1 = gauss;
                    else if (s == 2) g2 = gauss; else g3 = gauss;
#endif
                }
                slot[c] = s;
            }
            // Step 3: the sub-sample's weights added to its themes' slots.
#if TT_SHAPED == 1
            ivec3 l = ivec3(dot(vec4(luma), tt_slot_mask(slot.x)),
                            dot(vec4(luma), tt_slot_mask(slot.y)),
                            dot(vec4(luma), tt_slot_mask(slot.z)));
            ivec2 t = clamp(ivec2(floor(q + 0.5)), ivec2(0), last);
            ivec3 v = tt_border_weights(kt, wt, TT_FRAC, t, l);
            vec3 w = vec3(v) / float(v.x + v.y + v.z);
#else
            vec3 w = vec3(wt) / float(TT_FRAC);
#endif
            weight += w.x * tt_slot_mask(slot.x) + w.y * tt_slot_mask(slot.y)
                    + w.z * tt_slot_mask(slot.z);
        }
    }
    weight /= weight.x + weight.y + weight.z + weight.w;
#if TT_BLEND == 1
    // Histogram-preserving blend of the filtered Gaussianised themes (a theme alone is itself).
    vec3 g = (weight.x * g0 + weight.y * g1 + weight.z * g2 + weight.w * g3)
             / sqrt(dot(weight, weight));
    vec3 rgb = vec3(0.0);
    if (weight.x > 0.0) rgb += weight.x * (weight.x == 1.0 ? c0 : tt_inverse(themes.x, g) / 255.0);
    if (weight.y > 0.0) rgb += weight.y * tt_inverse(themes.y, g) / 255.0;
    if (weight.z > 0.0) rgb += weight.z * tt_inverse(themes.z, g) / 255.0;
    if (weight.w > 0.0) rgb += weight.w * tt_inverse(themes.w, g) / 255.0;
#else
    vec3 rgb = weight.x * c0 + weight.y * c1 + weight.z * c2 + weight.w * c3;
#endif
#if TT_COLOUR_MAP == 1
    rgb = min(rgb * tt_colour_filtered(centre, dx, dy), 1.0);
#endif
    return vec4(rgb, 1.0);
}
