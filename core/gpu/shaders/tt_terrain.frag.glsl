#version 330 core
// terratheme terrain fragment shader: the blend rule per pixel (docs/gpu.md).
//
// Input: v_texel, the texel position of the fragment in the full texture
// (texel X's centre at X; see tt_blend.glsl for the convention, every
// texture, uniform and define). Any vertex shader can supply it: a screen
// rectangle for a flat render (tt_rect.vert.glsl), or the ground plane of a
// 3D view (a perspective mapping; compile with TT_FILTERED 1 for mipmaps and
// anisotropic filtering).
// Output: f_colour, RGBA (alpha 1). With TT_FILTERED 0 the colour is exactly
// the CPU renderer's 8-bit texel (write it to an 8-bit normalised target).
#include "tt_blend.glsl"

in vec2 v_texel;
out vec4 f_colour;

void main() {
    f_colour = tt_shade(v_texel);
}
