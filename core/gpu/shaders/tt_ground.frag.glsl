#version 330 core
// terratheme ground fragment shader (docs/gpu.md): the blend rule on the
// ground plane of a perspective view, filtered path (compile with
// TT_FILTERED 1; TT_WRAP 1 for the flat plane, whose texture repeats).
//
// TT_GROUND_MESH 0 (flat plane): each pixel finds its ground point by eq. 1
// of core.perspective (U = (Au x + Bu y + Cu) / z, ...; x, y the screen
// position, pixel centres at +0.5, row 0 at the top) and its footprint by
// eq. 2 (dU/dx = (Au - Az U) / z, ...); pixels with z <= 0 show the sky.
//   tt_plane   mat3: column i = (A, B, C) of U, V, z for i = 0, 1, 2 (the
//              row-major PlaneMapping.coefficients() uploaded as they are)
//   tt_screen  vec2: screen y = tt_screen.x + tt_screen.y * gl_FragCoord.y
//              ((0, 1) for a framebuffer read back, (h, -1) on a display)
//   tt_sky     vec3: the sky's colour
// TT_GROUND_MESH 1 (mesh displaced by a height map): v_texel from
// tt_ground.vert.glsl, the footprint from its screen derivatives.
// TT_BASE 1: footprints a base texel wide or more read the base map (the
// render itself, mipmapped: core.gpu.base_map), narrower ones the per-pixel
// blend, mixed over the octave between:
//   tt_base       sampler2D RGBA8: the render at tt_base_step texels per texel,
//                 REPEAT, mipmapped (the sampler's anisotropy, or TT_PROBES)
//   tt_base_step  float: texels of the render per base texel
//   tt_base_span  vec2: texels of the render the base map covers
// Textures and the other uniforms: tt_blend.glsl. Output: f_colour, RGBA.
#include "tt_blend.glsl"

in vec2 v_texel;
out vec4 f_colour;
#if TT_GROUND_MESH == 0
uniform mat3 tt_plane;
uniform vec2 tt_screen;
uniform vec3 tt_sky;
#endif

#ifndef TT_BASE
#define TT_BASE 0
#endif
#if TT_BASE == 1
uniform sampler2D tt_base;
uniform float tt_base_step;
uniform vec2 tt_base_span;

// The base map over the footprint: the render's own average there.
vec3 tt_base_colour(vec2 p, vec2 dx, vec2 dy) {
    vec2 at = (tt_place(p) + 0.5) / tt_base_span;
#if TT_PROBES > 1
    return tt_probe(tt_base, at, dx / tt_base_span, dy / tt_base_span);
#else
    return textureGrad(tt_base, at, dx / tt_base_span, dy / tt_base_span).rgb;
#endif
}

// The base map's share: 0 for footprints under half a base texel wide, 1 from one
// (the width a 16x anisotropic filter averages across).
float tt_base_share(vec2 dx, vec2 dy) {
    float lx = length(dx), ly = length(dy);
    float width = max(min(lx, ly), max(lx, ly) / 16.0);
    return clamp(log2(width / tt_base_step) + 1.0, 0.0, 1.0);
}
#endif

// The ground's colour at texel position p, footprint (dx, dy).
vec4 tt_ground(vec2 p, vec2 dx, vec2 dy) {
#if TT_BASE == 1
    float t = tt_base_share(dx, dy);
    vec3 far = t > 0.0 ? tt_base_colour(p, dx, dy) : vec3(0.0);
    vec3 near = t < 1.0 ? tt_shade_footprint(p, dx, dy).rgb : vec3(0.0);
    return vec4(mix(near, far, t), 1.0);
#else
    return tt_shade_footprint(p, dx, dy);
#endif
}

// A footprint side no longer than the texture (past the horizon eq. 2 grows without bound).
vec2 tt_bounded(vec2 side) {
    float most = max(tt_texture_size.x, tt_texture_size.y);
    float len = length(side);
    return len > most ? side * (most / len) : side;
}

void main() {
#if TT_GROUND_MESH == 1
    f_colour = tt_ground(v_texel, tt_bounded(dFdx(v_texel)), tt_bounded(dFdy(v_texel)));
#else
    // Eq. 1 at the pixel centre, then eq. 2 for its footprint.
    vec3 s = vec3(gl_FragCoord.x, tt_screen.x + tt_screen.y * gl_FragCoord.y, 1.0);
    vec3 h = s * tt_plane;
    if (h.z <= 0.0) {
        f_colour = vec4(tt_sky, 1.0);
        return;
    }
    vec2 uv = h.xy / h.z;
    vec2 dx = (vec2(tt_plane[0][0], tt_plane[1][0]) - tt_plane[2][0] * uv) / h.z;
    vec2 dy = (vec2(tt_plane[0][1], tt_plane[1][1]) - tt_plane[2][1] * uv) / h.z;
    f_colour = tt_ground(uv - 0.5, tt_bounded(dx), tt_bounded(dy));
#endif
}
