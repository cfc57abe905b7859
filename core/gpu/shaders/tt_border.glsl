// terratheme shaped boundaries (core.render.boundary; docs/gpu.md), GLSL 3.30 core.
//
// Included by tt_blend.glsl when TT_SHAPED is 1. A border between themes is
// a narrow irregular edge decided per texel in integers (units of 1/1024 of
// a weight), exactly as the CPU renderer decides it:
//   1. w_t = floor(1024 * W_t / D), the barycentric weight of each theme;
//   2. s_t = w_t + floor(noise * n_t(X, Y) / 256) + floor(height * (luma_t - 128) * 4 / 256),
//      n_t value noise in -512..508 on a lattice of L texels (bilinear between
//      32-bit hashed lattice values), luma_t = (77 R + 150 G + 29 B) >> 8 of
//      the theme's texel;
//   3. v_t = max(0, s_t - max_u s_u + width) over the themes of non-zero weight.
// Every intermediate fits 32 bits: the hash wraps modulo 2^32 as in the CPU
// kernel's masked arithmetic; 1024 * W_t (up to 2^33) and the noise's
// 4 * sum (up to 1020 L^2) are divided by tt_quotient from their low 32 bits,
// exact for D <= 2^23 and L <= 2^15 (the renderer checks both).
//
// Uniforms:
//   tt_border       ivec4: width (1/1024 of a weight), noise and height
//                   (1/256), lattice L (texels): BoundaryOptions.parameters(N, M)
//   tt_border_seed  uint: the noise seed

uniform ivec4 tt_border;
uniform uint tt_border_seed;

// The lattice point's hash, 0..255 (core.render.boundary.lattice_value).
uint tt_lattice_value(uint ix, uint iy, uint theme) {
    uint h = (ix * 0x8DA6B343u) ^ (iy * 0xD8163841u) ^ (theme * 0xCB1AB31Fu) ^ tt_border_seed;
    h ^= h >> 16;
    h *= 0x7FEB352Du;
    h ^= h >> 15;
    h *= 0x846CA68Bu;
    h ^= h >> 16;
    return h >> 24;
}

// Value noise of theme k at global texel t (t >= 0), in -512..508.
int tt_noise(ivec2 t, uint k) {
    int lattice = tt_border.w;
    float inv = 1.0 / float(lattice);
    ivec2 qx = tt_divmod(t.x, lattice, inv);
    ivec2 qy = tt_divmod(t.y, lattice, inv);
    uvec2 i = uvec2(qx.x, qy.x);
    uvec2 f = uvec2(qx.y, qy.y);
    uvec2 g = uvec2(lattice) - f;
    uint top = g.x * tt_lattice_value(i.x, i.y, k) + f.x * tt_lattice_value(i.x + 1u, i.y, k);
    uint bottom = g.x * tt_lattice_value(i.x, i.y + 1u, k)
                + f.x * tt_lattice_value(i.x + 1u, i.y + 1u, k);
    // 4 * (gy * top + fy * bottom) / L^2, from its low 32 bits and a float estimate.
    float area = float(lattice) * float(lattice);
    float e = 4.0 * (float(g.y) * float(top) + float(f.y) * float(bottom)) / area;
    uint num = 4u * (g.y * top + f.y * bottom);
    return int(tt_quotient(num, uint(lattice * lattice), e)) - 512;
}

// Luminance of an 8-bit texel, 0..255.
int tt_luma(uvec3 rgb) {
    return int((77u * rgb.r + 150u * rgb.g + 29u * rgb.b) >> 8);
}

// Step 2: the score of theme k of weight w (out of d) at texel t.
int tt_border_score(uint k, int w, int d, ivec2 t, int luma) {
    int w1024 = int(tt_quotient(uint(w) << 10, uint(d), float(w) * 1024.0 / float(d)));
    return w1024 + ((tt_border.y * tt_noise(t, k)) >> 8)
                 + ((tt_border.z * (luma - 128) * 4) >> 8);
}

// Steps 2-3 for the three corner slots of a triangle (equal themes merged,
// tt_merge_equal): the border weights v (0 for slots of zero weight).
ivec3 tt_border_weights(uvec3 kt, ivec3 wt, int d, ivec2 t, ivec3 luma) {
    const int LOW = -(1 << 30);
    ivec3 s = ivec3(LOW);
    if (wt.x != 0) s.x = tt_border_score(kt.x, wt.x, d, t, luma.x);
    if (wt.y != 0) s.y = tt_border_score(kt.y, wt.y, d, t, luma.y);
    if (wt.z != 0) s.z = tt_border_score(kt.z, wt.z, d, t, luma.z);
    int best = max(max(s.x, s.y), s.z);
    ivec3 v = max(s - best + tt_border.x, 0);
    return ivec3(notEqual(wt, ivec3(0))) * v;
}
