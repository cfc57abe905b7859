#version 330 core
// terratheme uniform-cell fragment shader (exact path, docs/gpu.md).
//
// Fills a rectangle of cells whose four corners all carry one theme: the
// result is that theme's texel (the blend rule's step 1), so the grid and the
// weights need not be read. The headless renderer (core.gpu) draws runs of
// uniform cells with this shader and the other cells with
// tt_terrain.frag.glsl; an engine can use tt_terrain.frag.glsl alone.
//
// Inputs (from tt_rect.vert.glsl): v_texel (texel position, centre of texel X
// at X), v_theme (the rectangle's theme), v_theme_size ((w, h, 1/w, 1/h) of
// that theme). Textures and uniforms: tt_themes (and with TT_COLOUR_MAP 1
// tt_colour_map, tt_texture_size), as in tt_blend.glsl.
#include "tt_blend.glsl"

in vec2 v_texel;
flat in int v_theme;
flat in vec4 v_theme_size;
out vec4 f_colour;

void main() {
    ivec2 t = ivec2(floor(v_texel + 0.5));
    f_colour = tt_output_exact(tt_texel_sized(uint(v_theme), v_theme_size, t), t);
}
