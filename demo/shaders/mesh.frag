// Vulkan back end, fragment stage: the shading model shared with the GL back end (one golden
// image holds for both).
#version 450

layout(location = 0) in vec3 worldPosition;
layout(location = 1) in vec3 worldNormal;
layout(location = 2) in float scalar;

layout(set = 0, binding = 0) uniform Frame {
  mat4 viewProj;
  vec4 eye;
}
frame;

// One uint per triangle, indexed by gl_PrimitiveID (triangles of the draw in index order).
layout(set = 1, binding = 0) readonly buffer Cracks { uint flag[]; }
cracks;

layout(push_constant) uniform Draw {
  mat4 model;
  vec4 colour;       // w: 1 when the mesh has a scalar stream
  vec4 crackColour;  // w: 1 when the mesh has crack flags
}
draw;

layout(location = 0) out vec4 outColour;

vec3 colourMap(float s) {
  const vec3 stops[5] = vec3[](vec3(0.1, 0.2, 0.9), vec3(0.1, 0.8, 0.9), vec3(0.2, 0.85, 0.2),
                               vec3(0.95, 0.9, 0.1), vec3(0.9, 0.15, 0.1));
  const float x = clamp(s, 0.0, 1.0) * 4.0;
  const int i = min(int(x), 3);
  return mix(stops[i], stops[i + 1], x - float(i));
}

void main() {
  vec3 n = normalize(worldNormal);
  // Two-sided: crack slits are seen from both sides.
  if (!gl_FrontFacing) n = -n;
  const vec3 l = normalize(vec3(0.4, 1.0, 0.3));
  const vec3 v = normalize(frame.eye.xyz - worldPosition);
  const vec3 h = normalize(l + v);
  vec3 base = draw.colour.w != 0.0 ? colourMap(scalar) : draw.colour.rgb;
  if (draw.crackColour.w != 0.0 && cracks.flag[gl_PrimitiveID] != 0u) base = draw.crackColour.rgb;
  const float ambient = mix(0.18, 0.38, 0.5 * (n.y + 1.0));
  const float diffuse = 0.72 * max(dot(n, l), 0.0);
  const float specular = 0.12 * pow(max(dot(n, h), 0.0), 48.0);
  const vec3 linear = base * (ambient + diffuse) + vec3(specular);
  // The target is UNORM, not sRGB: encode here.
  outColour = vec4(pow(clamp(linear, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
