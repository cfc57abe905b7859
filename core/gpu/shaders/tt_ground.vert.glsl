#version 330 core
// terratheme ground vertex shader (docs/gpu.md): the textured ground plane of
// a perspective view (the fly-over, core.gpu.ground).
//
// TT_GROUND_MESH 0 (flat plane): one triangle covering the screen, no
// attributes; the fragment shader maps every pixel to the plane itself
// (eq. 1 of core.perspective, exact and wrapping to the horizon).
// TT_GROUND_MESH 1 (displaced by a height map): a grid mesh over the texture.
//   tt_edge          vec2 attribute: the vertex's ground position (U, V) in
//                    texel edges (texel X spans [X, X + 1))
//   tt_clip          mat4: ground (U, V, height, 1) to clip space
//                    (core.gpu.flight.clip_matrix)
//   tt_height        sampler2D R32F: the height map over the whole texture
//                    (LINEAR, clamped), values times tt_height_scale texels
//   tt_texture_size  vec2: the texture's size (W, H) in texels
// Output: v_texel (texel position, centre of texel X at X).

#ifndef TT_GROUND_MESH
#define TT_GROUND_MESH 0
#endif

out vec2 v_texel;

#if TT_GROUND_MESH == 1
in vec2 tt_edge;
uniform mat4 tt_clip;
uniform sampler2D tt_height;
uniform float tt_height_scale;
uniform vec2 tt_texture_size;

void main() {
    float h = textureLod(tt_height, tt_edge / tt_texture_size, 0.0).r * tt_height_scale;
    v_texel = tt_edge - 0.5;
    gl_Position = tt_clip * vec4(tt_edge, h, 1.0);
}
#else
void main() {
    vec2 corner = vec2((gl_VertexID & 1) * 4 - 1, (gl_VertexID & 2) * 2 - 1);
    v_texel = vec2(0.0);
    gl_Position = vec4(corner, 0.0, 1.0);
}
#endif
