// Vulkan back end, shadow pass: depth from the key light (no fragment stage).
#version 450

layout(location = 0) in vec3 inPosition;

layout(set = 0, binding = 0) uniform Frame {
  mat4 viewProj;
  vec4 eye;
  mat4 lightViewProj;  // Vulkan-corrected, like viewProj
  vec4 shadow;
}
frame;

layout(push_constant) uniform Draw { mat4 model; }
draw;

void main() { gl_Position = frame.lightViewProj * (draw.model * vec4(inPosition, 1.0)); }
