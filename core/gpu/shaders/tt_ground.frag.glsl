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
// Textures and the other uniforms: tt_blend.glsl. Output: f_colour, RGBA.
#include "tt_blend.glsl"

in vec2 v_texel;
out vec4 f_colour;
#if TT_GROUND_MESH == 0
uniform mat3 tt_plane;
uniform vec2 tt_screen;
uniform vec3 tt_sky;
#endif

// A footprint side no longer than the texture (past the horizon eq. 2 grows without bound).
vec2 tt_bounded(vec2 side) {
    float most = max(tt_texture_size.x, tt_texture_size.y);
    float len = length(side);
    return len > most ? side * (most / len) : side;
}

void main() {
#if TT_GROUND_MESH == 1
    f_colour = tt_shade_footprint(v_texel, tt_bounded(dFdx(v_texel)), tt_bounded(dFdy(v_texel)));
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
    f_colour = tt_shade_footprint(uv - 0.5, tt_bounded(dx), tt_bounded(dy));
#endif
}
