#version 330 core
// terratheme present shader (docs/gpu.md): a frame drawn at a reduced size,
// stretched over the target with bilinear filtering (the fly-over draws at
// part resolution while the camera moves). Drawn with tt_ground.vert.glsl
// (TT_GROUND_MESH 0: one triangle over the screen).
//   tt_frame   sampler2D RGBA8: the reduced frame, LINEAR, clamped
//   tt_target  vec2: the target's size in pixels
// Output: f_colour, the frame's colour at this pixel.

uniform sampler2D tt_frame;
uniform vec2 tt_target;
in vec2 v_texel;
out vec4 f_colour;

void main() {
    f_colour = texture(tt_frame, gl_FragCoord.xy / tt_target);
}
