#version 330 core
// terratheme rectangle vertex shader (docs/gpu.md): flat renders of the
// texture, rectangles drawn as pairs of triangles.
//
// Attributes:
//   tt_edge  vec2: the vertex's position in texel edges (texel X spans
//            [X, X + 1) in edge coordinates)
// Uniforms:
//   tt_view  vec4: x0, y0, width, height (texel edges) of the part of the
//            texture the framebuffer shows; framebuffer row 0 is texel row y0
//            (the top row of the image)
// Output: v_texel (texel position, centre of texel X at X).

in vec2 tt_edge;
uniform vec4 tt_view;
out vec2 v_texel;

void main() {
    v_texel = tt_edge - 0.5;
    gl_Position = vec4((tt_edge - tt_view.xy) / tt_view.zw * 2.0 - 1.0, 0.0, 1.0);
}
