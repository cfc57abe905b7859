#version 330 core
// terratheme copy fragment shader: rectangles of uniform cells (exact path, docs/gpu.md).
//
// A cell whose four corners carry one theme shows that theme's texels (the
// blend rule's step 1), so neither the grid nor the weights need reading:
// the headless renderer (core.gpu) draws runs of uniform cells with this
// shader, one draw per theme, and the other cells with tt_terrain.frag.glsl.
// An engine can use tt_terrain.frag.glsl alone; this is a speed-up.
//
// Inputs (from tt_rect.vert.glsl): v_uv, the theme coordinate (texel X of
// the theme at u = (X + 0.5) / w, any whole number of periods added), and
// v_texel (texel position, centre of texel X at X; read with TT_COLOUR_MAP 1).
// Texture: tt_theme, sampler2D RGBA8 of the theme alone, NEAREST, REPEAT
// (the hardware wraps at the theme's own size, so the texels are exact).
// With TT_COLOUR_MAP 1 also tt_colour_map and tt_colour_scale (tt_colour.glsl).
#include "tt_blend.glsl"

uniform sampler2D tt_theme;
in vec2 v_uv;
in vec2 v_texel;
out vec4 f_colour;

void main() {
    vec4 colour = texture(tt_theme, v_uv);
#if TT_COLOUR_MAP == 1
    f_colour = tt_output_exact(uvec3(colour.rgb * 255.0 + 0.5), ivec2(floor(v_texel + 0.5)));
#else
    f_colour = colour;
#endif
}
