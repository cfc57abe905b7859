#version 330 core
// terratheme rectangle vertex shader (docs/gpu.md): one instance per
// axis-aligned rectangle of the texture, drawn as a 4-vertex triangle strip.
//
// Per-instance attributes:
//   tt_rect        vec4: x0, y0, x1, y1, the rectangle's edges in texels
//                  (texel X spans [X, X + 1) in edge coordinates)
//   tt_rect_theme  int: the theme of a rectangle of uniform cells (for
//                  tt_uniform.frag.glsl), -1 for one the blend shader fills
// Uniforms:
//   tt_view        vec4: x0, y0, width, height (texel edges) of the part of
//                  the texture the framebuffer shows; framebuffer row 0 is
//                  texel row y0 (the top row of the image)
//   tt_theme_size  vec4[TT_THEMES]: as in tt_blend.glsl
// Outputs: v_texel (texel position, centre of texel X at X), v_theme,
// v_theme_size.

in vec4 tt_rect;
in int tt_rect_theme;
uniform vec4 tt_view;
uniform vec4 tt_theme_size[TT_THEMES];
out vec2 v_texel;
flat out int v_theme;
flat out vec4 v_theme_size;

void main() {
    vec2 corner = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
    vec2 edge = mix(tt_rect.xy, tt_rect.zw, corner);
    v_texel = edge - 0.5;
    v_theme = tt_rect_theme;
    v_theme_size = tt_theme_size[max(tt_rect_theme, 0)];
    gl_Position = vec4((edge - tt_view.xy) / tt_view.zw * 2.0 - 1.0, 0.0, 1.0);
}
