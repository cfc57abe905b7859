// terratheme colour map (core.model.colour_map; docs/gpu.md), GLSL 3.30 core.
//
// Included by tt_blend.glsl when TT_COLOUR_MAP is 1. A low-resolution RGB
// gain over the whole texture, 128 neutral: map pixel (i, j) covers texels
// [i*s, (i+1)*s) x [j*s, (j+1)*s) and sits at its centre, so at texel X the
// map coordinate is (X + 0.5) / s - 0.5 (clamped to the edge pixels).
//
// Exact path (tt_colour_exact): the CPU renderer's integers
// (core.render.colour_map): along each axis t = 2X + 1 - s, i0 = floor(t / 2s)
// and weights 2s - (t - 2s*i0), t - 2s*i0 of map pixels i0 and i0 + 1; the
// texel v becomes min(255, floor((v * G + 256 s^2) / (512 s^2))), G the
// integer bilinear sum, divided by tt_quotient from its low 32 bits: exact
// for s <= 1448 (512 s^2 <= 2^30; the renderer checks).
// Filtered path (tt_colour_filtered in tt_filtered.glsl): the map filtered
// over the pixel's footprint at the same coordinate, for any scale or angle.
//
// Uniforms:
//   tt_colour_map    sampler2D RGBA8 (mh x mw): the map, CLAMP_TO_EDGE,
//                    LINEAR_MIPMAP_LINEAR with mipmaps (texelFetch reads level 0)
//   tt_colour_scale  int: s, texels per map pixel

uniform sampler2D tt_colour_map;
uniform int tt_colour_scale;

// Map pixels (i0, i1) and their weights (w0, w1), summing to 2s, of texel x along one axis.
ivec4 tt_colour_axis(int x, int s, int size) {
    ivec2 q = tt_divmod(2 * x + 1 - s, 2 * s, 0.5 / float(s));
    if (q.x < 0) q = ivec2(0, 0);
    if (q.x >= size - 1) q = ivec2(size - 1, 0);
    return ivec4(q.x, min(q.x + 1, size - 1), 2 * s - q.y, q.y);
}

uvec3 tt_colour_value(int i, int j) {
    return uvec3(texelFetch(tt_colour_map, ivec2(i, j), 0).rgb * 255.0 + 0.5);
}

// The 8-bit texel rgb at global texel t times the map's gain, rounded half up, capped at 255.
uvec3 tt_colour_exact(uvec3 rgb, ivec2 t) {
    ivec2 size = textureSize(tt_colour_map, 0);
    int s = tt_colour_scale;
    ivec4 ax = tt_colour_axis(t.x, s, size.x);
    ivec4 ay = tt_colour_axis(t.y, s, size.y);
    // Along x (at most 2s * 255), then along y (wraps past 2^32 for large s).
    uvec3 top = uint(ax.z) * tt_colour_value(ax.x, ay.x) + uint(ax.w) * tt_colour_value(ax.y, ay.x);
    uvec3 bottom = uint(ax.z) * tt_colour_value(ax.x, ay.y)
                 + uint(ax.w) * tt_colour_value(ax.y, ay.y);
    uvec3 gain = uint(ay.z) * top + uint(ay.w) * bottom;
    float fs = float(s);
    uint half_den = uint(256 * s * s);
    vec3 g = float(ay.z) * vec3(top) + float(ay.w) * vec3(bottom);
    vec3 e = (vec3(rgb) * g + 256.0 * fs * fs) / (512.0 * fs * fs);
    return min(tt_quotient3(rgb * gain + half_den, 2u * half_den, e), uvec3(255u));
}
