// Vulkan back end, fragment stage: the shading model shared with the GL back end (one golden
// image holds for both). Without shadows, grid or crack look it is the plain model of
// docs/design.md ("The demo renderer"), which the tests evaluate on the CPU.
#version 450

layout(location = 0) in vec3 worldPosition;
layout(location = 1) in vec3 worldNormal;
layout(location = 2) in float scalar;
layout(location = 3) in vec2 uv;

layout(set = 0, binding = 0) uniform Frame {
  mat4 viewProj;
  vec4 eye;
  mat4 lightViewProj;  // depth in [0, 1], y down, like viewProj
  vec4 shadow;         // x: 1 = shadows on, y: shadow map texel, z: normal offset [m]
}
frame;
layout(set = 0, binding = 1) uniform sampler2DShadow shadowMap;

// One uint per triangle, indexed by gl_PrimitiveID (triangles of the draw in index order).
layout(set = 1, binding = 0) readonly buffer Cracks { uint flag[]; }
cracks;
// The mesh's colour texture (sRGB: sampled as linear light); a 1x1 white one when it has none.
layout(set = 2, binding = 0) uniform sampler2D colourTexture;

layout(push_constant) uniform Draw {
  mat4 model;
  vec4 colour;       // w: 1 when the mesh has a scalar stream
  vec4 crackColour;  // w: 1 when the mesh has crack flags
  vec4 look;         // crack faces: specular, shininess, grain, metallic
  vec4 ground;       // x: grid cell [m], 0 = none; y: 1 = textured; z: first triangle
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

// Value noise in [0, 1] (pores of bread crumb, the grain of a steel break).
float hash(vec3 p) {
  p = fract(p * 0.3183099 + 0.1) * 17.0;
  return fract(p.x * p.y * p.z * (p.x + p.y + p.z));
}
float noise(vec3 x) {
  const vec3 i = floor(x);
  vec3 f = fract(x);
  f = f * f * (3.0 - 2.0 * f);
  return mix(mix(mix(hash(i), hash(i + vec3(1, 0, 0)), f.x),
                 mix(hash(i + vec3(0, 1, 0)), hash(i + vec3(1, 1, 0)), f.x), f.y),
             mix(mix(hash(i + vec3(0, 0, 1)), hash(i + vec3(1, 0, 1)), f.x),
                 mix(hash(i + vec3(0, 1, 1)), hash(i + vec3(1, 1, 1)), f.x), f.y),
             f.z);
}

// Share of the key light reaching p: four bilinear comparison taps half a texel off centre
// (percentage-closer filtering over 3x3 texels), so edges are soft rather than stair-stepped;
// four taps rather than nine keep lavapipe's cost down.
float lightReaching(vec3 p, vec3 n) {
  if (frame.shadow.x == 0.0) return 1.0;
  const vec4 c = frame.lightViewProj * vec4(p + frame.shadow.z * n, 1.0);
  const vec3 s = c.xyz / c.w;
  const float depth = min(s.z, 1.0);  // beyond the far plane: nothing there casts
  const vec2 uv = s.xy * 0.5 + 0.5;
  float sum = 0.0;
  for (int k = 0; k < 4; ++k) {
    const vec2 offset = vec2(k & 1, k >> 1) - 0.5;
    sum += texture(shadowMap, vec3(uv + offset * frame.shadow.y, depth));
  }
  return 0.25 * sum;
}

void main() {
  const vec3 v = normalize(frame.eye.xyz - worldPosition);
  // The triangle's own plane, for flat-shaded crack facets (taken here, in uniform control flow).
  const vec3 facet = cross(dFdx(worldPosition), dFdy(worldPosition));
  // gl_PrimitiveID counts from the draw's first triangle: ground.z is that triangle's index.
  const bool crack =
      draw.crackColour.w != 0.0 && cracks.flag[gl_PrimitiveID + int(draw.ground.z)] != 0u;
  vec3 n = normalize(worldNormal);
  // Two-sided: crack slits are seen from both sides.
  if (!gl_FrontFacing) n = -n;
  vec3 base = draw.colour.w != 0.0 ? colourMap(scalar) : draw.colour.rgb;
  // Sampled here, in uniform control flow (implicit derivatives pick the mip level); v runs up
  // from the image's bottom row, which is the texture's last.
  if (draw.ground.y != 0.0) base *= texture(colourTexture, vec2(uv.x, 1.0 - uv.y)).rgb;
  float specular = 0.12, shininess = 48.0, metallic = 0.0;
  if (crack) {
    if (length(facet) > 0.0) n = normalize(dot(facet, v) < 0.0 ? -facet : facet);
    base = draw.crackColour.rgb;
    specular = draw.look.x;
    shininess = draw.look.y;
    metallic = draw.look.w;
    if (draw.look.z > 0.0)
      base *= 1.0 - draw.look.z * smoothstep(0.45, 0.8, noise(worldPosition * 450.0));
  }
  if (draw.ground.x > 0.0) {
    // Thin lines every cell and stronger ones every 5, faded out where they would alias, on
    // a faint checker: the floor shows its scale without drawing attention.
    const vec2 g = worldPosition.xz / draw.ground.x;
    const vec2 w = max(fwidth(g), vec2(1e-6));
    const vec2 d = abs(fract(g - 0.5) - 0.5) / w;
    const vec2 dm = abs(fract(g / 5.0 - 0.5) - 0.5) / (w / 5.0);
    const float fade = clamp(1.5 - 4.0 * max(w.x, w.y), 0.0, 1.0);
    const float minor = (1.0 - min(min(d.x, d.y), 1.0)) * fade;
    const float major = 1.0 - min(min(dm.x, dm.y) / 1.5, 1.0);
    const float checker = mod(floor(g.x) + floor(g.y), 2.0);
    base *= (1.0 - 0.05 * checker) * (1.0 - 0.22 * minor) * (1.0 - 0.35 * major);
  }
  const vec3 l = normalize(vec3(0.4, 1.0, 0.3));
  const vec3 h = normalize(l + v);
  const float lit = lightReaching(worldPosition, n);
  const float ambient = mix(0.18, 0.38, 0.5 * (n.y + 1.0));
  const float diffuse = 0.72 * max(dot(n, l), 0.0) * lit;
  const vec3 highlight = specular * pow(max(dot(n, h), 0.0), shininess) * lit *
                         mix(vec3(1.0), base, metallic);
  const vec3 linear = base * (1.0 - 0.5 * metallic) * (ambient + diffuse) + highlight;
  // The target is UNORM, not sRGB: encode here.
  outColour = vec4(pow(clamp(linear, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
