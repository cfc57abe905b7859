// terratheme filtered path (docs/gpu.md): the blend rule at any scale or angle, GLSL 3.30.
//
// Included by tt_blend.glsl when TT_FILTERED is 1 (its uniforms are listed
// there). A pixel's footprint is the parallelogram spanned by dx and dy (the
// texel steps of one pixel step along the screen axes: dFdx and dFdy of the
// texel position, or eq. 2 of a ground plane). The weights change at the cell
// scale, so they are sub-sampled over the footprint (two sub-samples per cell
// it spans along each side, at most tt_max_supersample); the themes carry the
// fine detail, so each distinct theme under the footprint is read once, over
// the whole footprint, with mipmaps and anisotropic filtering. The colour is
// sum(mean weight of theme t * filtered theme t): the linear blend, the shaped
// borders' weights (TT_SHAPED 1: the theme's luminance from its filtered
// read, the noise at the sub-sample's texel) or the histogram-preserving blend
// of the filtered Gaussianised themes (TT_BLEND 1). At one texel per pixel
// this is the exact render within a level or two (weights in 1/4096).

// Distinct themes one footprint can blend (the rest are dropped, weights renormalised).
const int TT_SLOTS = 4;

// Theme k at texel position p, filtered over the footprint (dx, dy) in texels.
vec3 tt_sample(uint k, vec2 p, vec2 dx, vec2 dy) {
    vec4 s = tt_theme_size[k];
    return textureGrad(tt_themes, vec3((p + 0.5) * s.zw, float(k)), dx * s.zw, dy * s.zw).rgb;
}
#if TT_BLEND == 1
vec3 tt_sample_gauss(uint k, vec2 p, vec2 dx, vec2 dy) {
    vec4 s = tt_theme_size[k];
    return textureGrad(tt_gauss, vec3((p + 0.5) * s.zw, float(k)), dx * s.zw, dy * s.zw).rgb;
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
    return clamp(int(ceil(2.0 * max(cells.x, cells.y) - 1e-4)), 1, tt_max_supersample);
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

// The pixel whose centre is at texel position p, footprint (dx, dy): RGBA in [0, 1].
vec4 tt_shade_footprint(vec2 p, vec2 dx, vec2 dy) {
    vec2 centre = tt_place(p);
    int sx = tt_steps(dx);
    int sy = tt_steps(dy);
    uint theme[TT_SLOTS];
    vec3 colour[TT_SLOTS];
    float weight[TT_SLOTS];
#if TT_SHAPED == 1
    int luma[TT_SLOTS];
    ivec2 last = ivec2(tt_texture_size) - 1;
#endif
#if TT_BLEND == 1
    vec3 gauss[TT_SLOTS];
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
                for (int s = 0; s < used; ++s) {
                    if (theme[s] == kt[c]) slot[c] = s;
                }
                if (slot[c] < 0 && used < TT_SLOTS) {
                    theme[used] = kt[c];
                    colour[used] = tt_sample(kt[c], centre, dx, dy);
                    weight[used] = 0.0;
#if TT_SHAPED == 1
                    luma[used] = tt_luma(uvec3(colour[used] * 255.0 + 0.5));
#endif
#if TT_BLEND == 1
                    gauss[used] = tt_sample_gauss(kt[c], centre, dx, dy);
#endif
                    slot[c] = used++;
                }
            }
            // Step 3: the sub-sample's weights added to its themes' slots.
#if TT_SHAPED == 1
            ivec3 l = ivec3(slot.x >= 0 ? luma[max(slot.x, 0)] : 0,
                            slot.y >= 0 ? luma[max(slot.y, 0)] : 0,
                            slot.z >= 0 ? luma[max(slot.z, 0)] : 0);
            ivec2 t = clamp(ivec2(floor(q + 0.5)), ivec2(0), last);
            ivec3 v = tt_border_weights(kt, wt, TT_FRAC, t, l);
            vec3 w = vec3(v) / float(v.x + v.y + v.z);
#else
            vec3 w = vec3(wt) / float(TT_FRAC);
#endif
            for (int c = 0; c < 3; ++c) {
                if (slot[c] >= 0) weight[slot[c]] += w[c];
            }
        }
    }
    float total = 0.0;
    for (int s = 0; s < used; ++s) total += weight[s];
    vec3 rgb = vec3(0.0);
#if TT_BLEND == 1
    // Histogram-preserving blend of the filtered Gaussianised themes.
    vec3 g = vec3(0.0);
    float norm = 0.0;
    for (int s = 0; s < used; ++s) {
        float w = weight[s] / total;
        g += w * gauss[s];
        norm += w * w;
    }
    g /= sqrt(norm);
    for (int s = 0; s < used; ++s) {
        float w = weight[s] / total;
        rgb += w * (w == 1.0 ? colour[s] * 255.0 : tt_inverse(theme[s], g));
    }
    rgb /= 255.0;
#else
    for (int s = 0; s < used; ++s) rgb += (weight[s] / total) * colour[s];
#endif
#if TT_COLOUR_MAP == 1
    rgb = min(rgb * tt_colour_filtered(centre, dx, dy), 1.0);
#endif
    return vec4(rgb, 1.0);
}
