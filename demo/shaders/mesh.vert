// Vulkan back end, vertex stage: world-space position and normal for the shared shading model
// (the GL back end has its own copy, written to the same rules).
#version 450

layout(location = 0) in vec3 inPosition;
layout(location = 1) in vec3 inNormal;

layout(set = 0, binding = 0) uniform Frame {
  mat4 viewProj;  // Vulkan-corrected: depth [0, 1], y down in clip space
  vec4 eye;
  mat4 lightViewProj;
  vec4 shadow;
}
frame;

// A readonly storage buffer rather than a vertex stream: a mesh without scalars binds a tiny
// zero buffer instead of a stream as long as its vertices.
layout(set = 1, binding = 1) readonly buffer Scalars { float value[]; }
scalars;
// Texture coordinates, the same way: read only when the mesh is textured.
layout(set = 1, binding = 2) readonly buffer Uvs { vec2 value[]; }
uvs;

layout(push_constant) uniform Draw {
  mat4 model;
  vec4 colour;       // w: 1 when the mesh has a scalar stream
  vec4 crackColour;  // w: 1 when the mesh has crack flags
  vec4 look;         // crack faces: specular, shininess, grain, metallic
  vec4 ground;       // x: grid cell [m], 0 = none; y: 1 = textured; z: first triangle
}
draw;

layout(location = 0) out vec3 worldPosition;
layout(location = 1) out vec3 worldNormal;
layout(location = 2) out float scalar;
layout(location = 3) out vec2 uv;

void main() {
  const vec4 world = draw.model * vec4(inPosition, 1.0);
  worldPosition = world.xyz;
  worldNormal = mat3(draw.model) * inNormal;
  scalar = draw.colour.w != 0.0 ? scalars.value[gl_VertexIndex] : 0.0;
  uv = draw.ground.y != 0.0 ? uvs.value[gl_VertexIndex] : vec2(0.0);
  gl_Position = frame.viewProj * world;
}
