// OpenGL back end: a core-profile context from EGL with no window system (Mesa's surfaceless
// platform, else the first EGL device, else the default display; a 1x1 pbuffer only where a
// context cannot be made current without a surface), drawing into an MSAA framebuffer object
// that is resolved and read back. Same shading as the Vulkan back end, including its shadow
// map: a depth-only pass from the key light into a depth texture sampled with comparison.
#define GL_GLEXT_PROTOTYPES 1  // glvnd's libOpenGL exports the core entry points directly
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/glcorearb.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <iterator>
#include <map>
#include <mutex>
#include <string_view>

#include "renderer.h"

namespace gf::demo {
namespace {

const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 inPosition;
layout(location = 1) in vec3 inNormal;
layout(location = 2) in float inScalar;
layout(location = 3) in vec2 inUv;
uniform mat4 uModel;
uniform mat4 uViewProj;
out vec3 vWorldPos;
out vec3 vNormal;
out float vScalar;
out vec2 vUv;
void main() {
  vUv = inUv;
  vec4 world = uModel * vec4(inPosition, 1.0);
  vWorldPos = world.xyz;
  vNormal = mat3(uModel) * inNormal;
  vScalar = inScalar;
  gl_Position = uViewProj * world;
}
)";

const char* kFragmentShader = R"(#version 330 core
in vec3 vWorldPos;
in vec3 vNormal;
in float vScalar;
in vec2 vUv;
uniform usamplerBuffer uCrackMask;
uniform sampler2D uTexture;  // sRGB: sampled as linear light
uniform sampler2DShadow uShadowMap;
uniform vec3 uEye;
uniform vec3 uColour;
uniform vec3 uCrackColour;
uniform int uHasScalar;
uniform int uHasCrack;
uniform mat4 uLightViewProj;
uniform vec4 uShadow;  // on, texel size, normal offset
uniform vec4 uLook;    // crack faces: specular, shininess, grain, metallic
uniform vec4 uGround;  // x: grid cell [m], y: 1 = textured
out vec4 outColour;

vec3 colourMap(float s) {
  const vec3 stops[5] = vec3[5](vec3(0.1, 0.2, 0.9), vec3(0.1, 0.8, 0.9), vec3(0.2, 0.85, 0.2),
                               vec3(0.95, 0.9, 0.1), vec3(0.9, 0.15, 0.1));
  float x = clamp(s, 0.0, 1.0) * 4.0;
  int i = min(int(x), 3);
  return mix(stops[i], stops[i + 1], x - float(i));
}

// Value noise in [0, 1] (pores of bread crumb, the grain of a steel break).
float hash(vec3 p) {
  p = fract(p * 0.3183099 + 0.1) * 17.0;
  return fract(p.x * p.y * p.z * (p.x + p.y + p.z));
}
float noise(vec3 x) {
  vec3 i = floor(x);
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
  if (uShadow.x == 0.0) return 1.0;
  vec4 c = uLightViewProj * vec4(p + uShadow.z * n, 1.0);
  vec3 s = c.xyz / c.w;
  float depth = min(s.z * 0.5 + 0.5, 1.0);  // beyond the far plane: nothing there casts
  vec2 uv = s.xy * 0.5 + 0.5;
  float sum = 0.0;
  for (int k = 0; k < 4; ++k) {
    vec2 offset = vec2(k & 1, k >> 1) - 0.5;
    sum += texture(uShadowMap, vec3(uv + offset * uShadow.y, depth));
  }
  return 0.25 * sum;
}

void main() {
  vec3 v = normalize(uEye - vWorldPos);
  // The triangle's own plane, for flat-shaded crack facets (in uniform control flow).
  vec3 facet = cross(dFdx(vWorldPos), dFdy(vWorldPos));
  // gl_PrimitiveID counts from the draw's first triangle: uGround.z is that triangle's index.
  bool crack =
      uHasCrack != 0 && texelFetch(uCrackMask, gl_PrimitiveID + int(uGround.z)).r != 0u;
  vec3 n = normalize(vNormal);
  // Two-sided: crack slits are seen from both sides.
  if (!gl_FrontFacing) n = -n;
  vec3 base = uHasScalar != 0 ? colourMap(vScalar) : uColour;
  // Sampled here, in uniform control flow (implicit derivatives pick the mip level); v runs up
  // from the image's bottom row, which is the texture's last.
  if (uGround.y != 0.0) base *= texture(uTexture, vec2(vUv.x, 1.0 - vUv.y)).rgb;
  float specular = 0.12, shininess = 48.0, metallic = 0.0;
  if (crack) {
    if (length(facet) > 0.0) n = normalize(dot(facet, v) < 0.0 ? -facet : facet);
    base = uCrackColour;
    specular = uLook.x;
    shininess = uLook.y;
    metallic = uLook.w;
    if (uLook.z > 0.0)
      base *= 1.0 - uLook.z * smoothstep(0.45, 0.8, noise(vWorldPos * 450.0));
  }
  if (uGround.x > 0.0) {
    // Thin lines every cell and stronger ones every 5, faded out where they would alias, on
    // a faint checker: the floor shows its scale without drawing attention.
    vec2 g = vWorldPos.xz / uGround.x;
    vec2 w = max(fwidth(g), vec2(1e-6));
    vec2 d = abs(fract(g - 0.5) - 0.5) / w;
    vec2 dm = abs(fract(g / 5.0 - 0.5) - 0.5) / (w / 5.0);
    float fade = clamp(1.5 - 4.0 * max(w.x, w.y), 0.0, 1.0);
    float minor = (1.0 - min(min(d.x, d.y), 1.0)) * fade;
    float major = 1.0 - min(min(dm.x, dm.y) / 1.5, 1.0);
    float checker = mod(floor(g.x) + floor(g.y), 2.0);
    base *= (1.0 - 0.05 * checker) * (1.0 - 0.22 * minor) * (1.0 - 0.35 * major);
  }
  vec3 l = normalize(vec3(0.4, 1.0, 0.3));
  vec3 h = normalize(l + v);
  float lit = lightReaching(vWorldPos, n);
  float ambient = mix(0.18, 0.38, 0.5 * (n.y + 1.0));
  float diffuse = 0.72 * max(dot(n, l), 0.0) * lit;
  vec3 highlight = specular * pow(max(dot(n, h), 0.0), shininess) * lit *
                         mix(vec3(1.0), base, metallic);
  vec3 linear = base * (1.0 - 0.5 * metallic) * (ambient + diffuse) + highlight;
  outColour = vec4(pow(clamp(linear, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
)";

// The shadow pass: depth only.
const char* kShadowVertexShader = R"(#version 330 core
layout(location = 0) in vec3 inPosition;
uniform mat4 uModel;
uniform mat4 uLightViewProj;
void main() { gl_Position = uLightViewProj * (uModel * vec4(inPosition, 1.0)); }
)";
const char* kShadowFragmentShader = R"(#version 330 core
void main() {}
)";

constexpr GLsizei kShadowSize = 1024;  // texels per side, as the Vulkan back end

std::string eglErrorName(EGLint e) {
  switch (e) {
    case EGL_SUCCESS:
      return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE:
      return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP:
      return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW:
      return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE:
      return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST:
      return "EGL_CONTEXT_LOST";
    default:
      return "EGL error " + std::to_string(e);
  }
}

std::string glErrorName(GLenum e) {
  switch (e) {
    case GL_INVALID_ENUM:
      return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:
      return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:
      return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION:
      return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY:
      return "GL_OUT_OF_MEMORY";
    default:
      return "GL error " + std::to_string(e);
  }
}

// Every pending GL error, comma separated; empty when there is none.
std::string drainGlErrors() {
  std::string s;
  for (int i = 0; i < 16; ++i) {  // bounded: a lost context may report errors forever
    const GLenum e = glGetError();
    if (e == GL_NO_ERROR) break;
    s += (s.empty() ? "" : ", ") + glErrorName(e);
  }
  return s;
}

bool hasExtension(const char* list, std::string_view name) {
  if (!list) return false;
  std::string_view all(list);
  for (size_t pos = 0; (pos = all.find(name, pos)) != std::string_view::npos; pos += name.size()) {
    const bool startOk = pos == 0 || all[pos - 1] == ' ';
    const bool endOk = pos + name.size() == all.size() || all[pos + name.size()] == ' ';
    if (startOk && endOk) return true;
  }
  return false;
}

// eglTerminate ends a display for every user in the process (displays are per native display,
// not per call), so renderers alive at the same time share it through a count.
std::mutex g_displayMutex;
std::map<EGLDisplay, int> g_displayUsers;

bool acquireDisplay(EGLDisplay display) {
  std::lock_guard<std::mutex> lock(g_displayMutex);
  if (g_displayUsers[display]++ > 0) return true;
  if (eglInitialize(display, nullptr, nullptr)) return true;
  g_displayUsers.erase(display);
  return false;
}

void releaseDisplay(EGLDisplay display) {
  std::lock_guard<std::mutex> lock(g_displayMutex);
  auto it = g_displayUsers.find(display);
  if (it == g_displayUsers.end() || --it->second > 0) return;
  g_displayUsers.erase(it);
  eglTerminate(display);
}

Result<GLuint> compileShader(GLenum stage, const char* source, const char* name) {
  const GLuint shader = glCreateShader(stage);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok) return shader;
  GLint length = 0;
  glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(size_t(std::max(length, 1)), '\0');
  glGetShaderInfoLog(shader, GLsizei(log.size()), nullptr, log.data());
  glDeleteShader(shader);
  return fail("GL: ", name, " shader does not compile: ", log.c_str());
}

// One mesh slot's GL objects, kept across frames.
struct Slot {
  GLuint vao = 0, positions = 0, normals = 0, scalar = 0, indices = 0, crack = 0, crackTexture = 0,
         uv = 0;
  uint32_t vertices = 0, triangles = 0;
  bool hasScalar = false, hasCrack = false, hasUv = false, uploaded = false;
  uint64_t topologyVersion = 0;
};

class GlRenderer final : public Renderer {
 public:
  ~GlRenderer() override;
  Result<void> init(const RendererOptions& options);
  const std::string& description() const override { return m_description; }
  Result<FrameStats> render(std::span<const MeshFrame> meshes, const Camera& camera,
                            const FrameOptions& options, Image& out) override;

 private:
  Result<void> createContext();
  Result<void> createContextOn(EGLDisplay display, const char* platform);
  Result<void> createPipeline(const RendererOptions& options);
  Result<void> makeCurrent();
  Result<void> upload(Slot& slot, const MeshFrame& mesh, FrameStats& stats);
  /// The GL texture of `texture`, uploaded (all mip levels) the first time it is seen.
  GLuint textureFor(const std::shared_ptr<const Texture>& texture);

  EGLDisplay m_display = EGL_NO_DISPLAY;
  EGLContext m_context = EGL_NO_CONTEXT;
  EGLSurface m_pbuffer = EGL_NO_SURFACE;
  std::string m_description;
  int m_width = 0, m_height = 0;
  GLuint m_program = 0, m_msaaFbo = 0, m_msaaColour = 0, m_msaaDepth = 0;
  GLuint m_resolveFbo = 0, m_resolveColour = 0;
  GLint m_uModel = -1, m_uViewProj = -1, m_uEye = -1, m_uColour = -1, m_uCrackColour = -1,
        m_uHasScalar = -1, m_uHasCrack = -1, m_uCrackMask = -1, m_uShadowMap = -1,
        m_uLightViewProj = -1, m_uShadow = -1, m_uLook = -1, m_uGround = -1, m_uTexture = -1;
  GLuint m_shadowProgram = 0, m_shadowFbo = 0, m_shadowTexture = 0;
  GLint m_uShadowModel = -1, m_uShadowLightViewProj = -1;
  GLint m_maxTextureBuffer = 0;
  std::vector<Slot> m_slots;
  // Kept alive with their GL names so that a pointer is never reused for another texture.
  std::map<const Texture*, std::pair<std::shared_ptr<const Texture>, GLuint>> m_textures;
};

Result<void> GlRenderer::createContextOn(EGLDisplay display, const char* platform) {
  if (display == EGL_NO_DISPLAY) return fail("no display");
  if (!acquireDisplay(display)) return fail("eglInitialize: ", eglErrorName(eglGetError()));
  m_display = display;
  if (!eglBindAPI(EGL_OPENGL_API))
    return fail("eglBindAPI(EGL_OPENGL_API): ", eglErrorName(eglGetError()));
  const bool surfaceless =
      hasExtension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context");
  const EGLint configAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE,
                                  surfaceless ? 0 : EGL_PBUFFER_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint count = 0;
  if (!eglChooseConfig(display, configAttribs, &config, 1, &count) || count == 0)
    return fail("eglChooseConfig: no OpenGL-capable config (", eglErrorName(eglGetError()), ")");
  // Core profile 4.5 where offered (llvmpipe does); 3.3 is all the shaders need.
  const EGLint versions[][2] = {{4, 5}, {3, 3}};
  for (const auto& v : versions) {
    const EGLint contextAttribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                     v[0],
                                     EGL_CONTEXT_MINOR_VERSION,
                                     v[1],
                                     EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                     EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                     EGL_NONE};
    m_context = eglCreateContext(display, config, EGL_NO_CONTEXT, contextAttribs);
    if (m_context != EGL_NO_CONTEXT) break;
  }
  if (m_context == EGL_NO_CONTEXT)
    return fail("eglCreateContext (core profile 3.3 or later): ", eglErrorName(eglGetError()));
  if (!surfaceless) {
    const EGLint pbufferAttribs[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
    m_pbuffer = eglCreatePbufferSurface(display, config, pbufferAttribs);
    if (m_pbuffer == EGL_NO_SURFACE)
      return fail("eglCreatePbufferSurface: ", eglErrorName(eglGetError()));
  }
  if (!eglMakeCurrent(display, m_pbuffer, m_pbuffer, m_context))
    return fail("eglMakeCurrent: ", eglErrorName(eglGetError()));
  const auto* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  m_description = std::string("OpenGL ") + (version ? version : "?") + ", " +
                  (renderer ? renderer : "?") + ", EGL " + platform;
  return {};
}

Result<void> GlRenderer::createContext() {
  const char* clientExtensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto getPlatformDisplay = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  std::string tried;
  // Undoes a failed attempt so the next one starts clean.
  auto reset = [&] {
    if (m_display == EGL_NO_DISPLAY) return;
    eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (m_pbuffer != EGL_NO_SURFACE) eglDestroySurface(m_display, m_pbuffer);
    if (m_context != EGL_NO_CONTEXT) eglDestroyContext(m_display, m_context);
    releaseDisplay(m_display);
    m_display = EGL_NO_DISPLAY;
    m_context = EGL_NO_CONTEXT;
    m_pbuffer = EGL_NO_SURFACE;
  };
  auto note = [&](const char* platform, const std::string& why) {
    tried += std::string(tried.empty() ? "" : "; ") + platform + ": " + why;
  };
  auto attempt = [&](EGLDisplay display, const char* platform) {
    Result<void> r = createContextOn(display, platform);
    if (r) return true;
    reset();
    note(platform, r.error().message);
    return false;
  };
  // GF_EGL_PLATFORM=surfaceless|device|default tries only that one (to check each path).
  const char* only = std::getenv("GF_EGL_PLATFORM");
  const std::string_view platforms[] = {"surfaceless", "device", "default"};
  if (only && std::find(std::begin(platforms), std::end(platforms), only) == std::end(platforms))
    return fail("GL: GF_EGL_PLATFORM='", only, "' is not surfaceless, device or default");
  auto wanted = [&](const char* platform) { return !only || std::string_view(only) == platform; };

  if (wanted("surfaceless")) {
    if (!getPlatformDisplay || !hasExtension(clientExtensions, "EGL_MESA_platform_surfaceless"))
      note("surfaceless", "EGL_MESA_platform_surfaceless not offered");
    else if (attempt(
                 getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
                 "surfaceless"))
      return {};
  }
  if (wanted("device")) {
    auto queryDevices =
        reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    EGLDeviceEXT device = nullptr;
    EGLint devices = 0;
    if (!getPlatformDisplay || !queryDevices ||
        !hasExtension(clientExtensions, "EGL_EXT_platform_device"))
      note("device", "EGL_EXT_platform_device not offered");
    else if (!queryDevices(1, &device, &devices) || devices == 0)
      note("device", "no EGL device");
    else if (attempt(getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, device, nullptr), "device"))
      return {};
  }
  if (wanted("default") && attempt(eglGetDisplay(EGL_DEFAULT_DISPLAY), "default")) return {};
  return fail("GL: no EGL context (", tried, ")");
}

Result<void> GlRenderer::makeCurrent() {
  if (eglGetCurrentContext() == m_context) return {};
  if (!eglMakeCurrent(m_display, m_pbuffer, m_pbuffer, m_context))
    return fail("GL: eglMakeCurrent: ", eglErrorName(eglGetError()));
  return {};
}

// Compiles and links a program into `program` (left for the destructor even on failure).
Result<void> linkProgram(const char* vertex, const char* fragment, const char* name,
                         GLuint& program) {
  Result<GLuint> vs = compileShader(GL_VERTEX_SHADER, vertex, "vertex");
  if (!vs) return vs.error();
  Result<GLuint> fs = compileShader(GL_FRAGMENT_SHADER, fragment, "fragment");
  if (!fs) {
    glDeleteShader(vs.value());
    return fs.error();
  }
  program = glCreateProgram();
  glAttachShader(program, vs.value());
  glAttachShader(program, fs.value());
  glLinkProgram(program);
  glDeleteShader(vs.value());  // flagged; freed with the program
  glDeleteShader(fs.value());
  GLint linked = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &linked);
  if (!linked) {
    GLint length = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
    std::string log(size_t(std::max(length, 1)), '\0');
    glGetProgramInfoLog(program, GLsizei(log.size()), nullptr, log.data());
    return fail("GL: ", name, " shader program does not link: ", log.c_str());
  }
  return {};
}

Result<void> GlRenderer::createPipeline(const RendererOptions& options) {
  if (Result<void> r = linkProgram(kVertexShader, kFragmentShader, "mesh", m_program); !r) return r;
  if (Result<void> r =
          linkProgram(kShadowVertexShader, kShadowFragmentShader, "shadow", m_shadowProgram);
      !r)
    return r;
  m_uShadowModel = glGetUniformLocation(m_shadowProgram, "uModel");
  m_uShadowLightViewProj = glGetUniformLocation(m_shadowProgram, "uLightViewProj");
  m_uShadowMap = glGetUniformLocation(m_program, "uShadowMap");
  m_uLightViewProj = glGetUniformLocation(m_program, "uLightViewProj");
  m_uShadow = glGetUniformLocation(m_program, "uShadow");
  m_uLook = glGetUniformLocation(m_program, "uLook");
  m_uGround = glGetUniformLocation(m_program, "uGround");
  m_uTexture = glGetUniformLocation(m_program, "uTexture");
  m_uModel = glGetUniformLocation(m_program, "uModel");
  m_uViewProj = glGetUniformLocation(m_program, "uViewProj");
  m_uEye = glGetUniformLocation(m_program, "uEye");
  m_uColour = glGetUniformLocation(m_program, "uColour");
  m_uCrackColour = glGetUniformLocation(m_program, "uCrackColour");
  m_uHasScalar = glGetUniformLocation(m_program, "uHasScalar");
  m_uHasCrack = glGetUniformLocation(m_program, "uHasCrack");
  m_uCrackMask = glGetUniformLocation(m_program, "uCrackMask");
  glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &m_maxTextureBuffer);

  GLint maxSamples = 1;
  glGetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  const int samples = std::clamp(options.samples, 1, std::max(maxSamples, 1));
  m_width = options.width;
  m_height = options.height;
  glGenRenderbuffers(1, &m_msaaColour);
  glBindRenderbuffer(GL_RENDERBUFFER, m_msaaColour);
  glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples > 1 ? samples : 0, GL_RGBA8, m_width,
                                   m_height);
  glGenRenderbuffers(1, &m_msaaDepth);
  glBindRenderbuffer(GL_RENDERBUFFER, m_msaaDepth);
  glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples > 1 ? samples : 0,
                                   GL_DEPTH_COMPONENT32F, m_width, m_height);
  glGenFramebuffers(1, &m_msaaFbo);
  glBindFramebuffer(GL_FRAMEBUFFER, m_msaaFbo);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, m_msaaColour);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m_msaaDepth);
  GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return fail("GL: ", std::to_string(samples), "x MSAA framebuffer ", std::to_string(m_width),
                "x", std::to_string(m_height), " incomplete (status ", std::to_string(status), ")");
  // The shadow map: a comparison-sampled depth texture, lit (depth 1) outside.
  glGenTextures(1, &m_shadowTexture);
  glBindTexture(GL_TEXTURE_2D, m_shadowTexture);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, kShadowSize, kShadowSize, 0,
               GL_DEPTH_COMPONENT, GL_FLOAT, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
  const float border[4] = {1, 1, 1, 1};
  glTexParameterfv(GL_TEXTURE_2D, GL_TEXTURE_BORDER_COLOR, border);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
  glBindTexture(GL_TEXTURE_2D, 0);
  glGenFramebuffers(1, &m_shadowFbo);
  glBindFramebuffer(GL_FRAMEBUFFER, m_shadowFbo);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, m_shadowTexture, 0);
  glDrawBuffer(GL_NONE);
  glReadBuffer(GL_NONE);
  status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return fail("GL: shadow framebuffer incomplete (status ", std::to_string(status), ")");
  glGenRenderbuffers(1, &m_resolveColour);
  glBindRenderbuffer(GL_RENDERBUFFER, m_resolveColour);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, m_width, m_height);
  glGenFramebuffers(1, &m_resolveFbo);
  glBindFramebuffer(GL_FRAMEBUFFER, m_resolveFbo);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, m_resolveColour);
  status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return fail("GL: resolve framebuffer incomplete (status ", std::to_string(status), ")");
  const std::string errors = drainGlErrors();
  if (!errors.empty()) return fail("GL: setting up the pipeline: ", errors);
  return {};
}

Result<void> GlRenderer::init(const RendererOptions& options) {
  Result<void> r = createContext();
  if (!r) return r;
  return createPipeline(options);
}

GlRenderer::~GlRenderer() {
  if (m_display == EGL_NO_DISPLAY) return;
  if (m_context != EGL_NO_CONTEXT && eglMakeCurrent(m_display, m_pbuffer, m_pbuffer, m_context)) {
    for (Slot& s : m_slots) {
      const GLuint buffers[] = {s.positions, s.normals, s.scalar, s.indices, s.crack, s.uv};
      glDeleteBuffers(6, buffers);
      glDeleteTextures(1, &s.crackTexture);
      glDeleteVertexArrays(1, &s.vao);
    }
    for (auto& [key, entry] : m_textures) glDeleteTextures(1, &entry.second);
    glDeleteProgram(m_program);
    glDeleteProgram(m_shadowProgram);
    glDeleteTextures(1, &m_shadowTexture);
    const GLuint fbos[] = {m_msaaFbo, m_resolveFbo, m_shadowFbo};
    glDeleteFramebuffers(3, fbos);
    const GLuint rbos[] = {m_msaaColour, m_msaaDepth, m_resolveColour};
    glDeleteRenderbuffers(3, rbos);
  }
  eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (m_pbuffer != EGL_NO_SURFACE) eglDestroySurface(m_display, m_pbuffer);
  if (m_context != EGL_NO_CONTEXT) eglDestroyContext(m_display, m_context);
  releaseDisplay(m_display);
}

Result<void> GlRenderer::upload(Slot& slot, const MeshFrame& mesh, FrameStats& stats) {
  const uint64_t vertices = mesh.positions.size() / 3, triangles = mesh.indices.size() / 3;
  if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0)
    return fail("positions (", std::to_string(mesh.positions.size()), ") and indices (",
                std::to_string(mesh.indices.size()), ") must be multiples of 3");
  if (mesh.normals.size() != mesh.positions.size())
    return fail("normals has ", std::to_string(mesh.normals.size()), " floats, positions ",
                std::to_string(mesh.positions.size()));
  if (!mesh.scalar.empty() && mesh.scalar.size() != vertices)
    return fail("scalar has ", std::to_string(mesh.scalar.size()), " values for ",
                std::to_string(vertices), " vertices");
  if (!mesh.crackMask.empty() && mesh.crackMask.size() != triangles)
    return fail("crackMask has ", std::to_string(mesh.crackMask.size()), " flags for ",
                std::to_string(triangles), " triangles");
  if (mesh.dirtyBegin > mesh.dirtyEnd || mesh.dirtyEnd > vertices)
    return fail("dirty range [", std::to_string(mesh.dirtyBegin), ", ",
                std::to_string(mesh.dirtyEnd), ") is outside 0..", std::to_string(vertices));
  const bool hasScalar = !mesh.scalar.empty(), hasCrack = !mesh.crackMask.empty();
  bool hasUv = mesh.texture != nullptr;
  for (const DrawRange& r : mesh.ranges) {
    if (uint64_t(r.firstTriangle) + r.triangleCount > triangles ||
        r.firstTriangle >= kMaxRangeStart)
      return fail("range of triangles [", std::to_string(r.firstTriangle), ", ",
                  std::to_string(uint64_t(r.firstTriangle) + r.triangleCount), ") is outside 0..",
                  std::to_string(triangles), " (or starts past 2^24)");
    hasUv = hasUv || r.texture != nullptr;
  }
  if (hasUv && mesh.uvs.size() != 2 * vertices)
    return fail("uvs has ", std::to_string(mesh.uvs.size()), " values for ",
                std::to_string(vertices), " vertices (2 each, needed with a texture)");
  if (vertices > UINT32_MAX)
    return fail(std::to_string(vertices), " vertices exceed 32-bit indices");
  if (hasCrack && triangles > uint64_t(std::max(m_maxTextureBuffer, 0)))
    return fail("crackMask: ", std::to_string(triangles),
                " triangles exceed the GL's texture buffer limit (",
                std::to_string(m_maxTextureBuffer), " texels)");
  const uint64_t vertexBytes = (hasScalar ? 7 : 6) * sizeof(float);
  const uint64_t fullBytes = vertices * vertexBytes +
                             triangles * (3 * sizeof(uint32_t) + (hasCrack ? 1 : 0)) +
                             (hasUv ? vertices * 2 * sizeof(float) : 0);
  stats.surfaceBytes += fullBytes;

  if (slot.vao == 0) {
    glGenVertexArrays(1, &slot.vao);
    GLuint buffers[5];
    glGenBuffers(5, buffers);
    slot.positions = buffers[0];
    slot.normals = buffers[1];
    slot.scalar = buffers[2];
    slot.indices = buffers[3];
    slot.crack = buffers[4];
    glGenTextures(1, &slot.crackTexture);
    glGenBuffers(1, &slot.uv);
  }
  const bool full = !slot.uploaded || slot.topologyVersion != mesh.topologyVersion ||
                    slot.vertices != vertices || slot.triangles != triangles ||
                    slot.hasScalar != hasScalar || slot.hasCrack != hasCrack || slot.hasUv != hasUv;
  // Marked stale first so a GL error below forces a full upload next frame.
  slot.uploaded = false;
  if (full) {
    for (uint32_t i : mesh.indices)
      if (i >= vertices)
        return fail("index ", std::to_string(i), " is out of range (", std::to_string(vertices),
                    " vertices)");
    glBindVertexArray(slot.vao);
    // One float attribute stream; absent, the location reads the constant set in render().
    const auto stream = [](GLuint location, GLuint buffer, std::span<const float> data,
                           GLint components, GLenum usage) {
      if (data.empty()) {
        glDisableVertexAttribArray(location);
        return;
      }
      glBindBuffer(GL_ARRAY_BUFFER, buffer);
      glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(data.size_bytes()), data.data(), usage);
      glVertexAttribPointer(location, components, GL_FLOAT, GL_FALSE, 0, nullptr);
      glEnableVertexAttribArray(location);
    };
    stream(0, slot.positions, mesh.positions, 3, GL_DYNAMIC_DRAW);
    stream(1, slot.normals, mesh.normals, 3, GL_DYNAMIC_DRAW);
    stream(2, slot.scalar, hasScalar ? mesh.scalar : std::span<const float>{}, 1, GL_DYNAMIC_DRAW);
    stream(3, slot.uv, hasUv ? mesh.uvs : std::span<const float>{}, 2, GL_STATIC_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, slot.indices);  // recorded in the VAO
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(mesh.indices.size_bytes()),
                 mesh.indices.data(), GL_DYNAMIC_DRAW);
    glBindVertexArray(0);
    // One byte per triangle, read as R8UI by gl_PrimitiveID. Without a mask the shader's
    // uHasCrack skips the fetch, as the Vulkan back end does, so no zeros are sent.
    if (hasCrack) {
      glBindBuffer(GL_TEXTURE_BUFFER, slot.crack);
      glBufferData(GL_TEXTURE_BUFFER, GLsizeiptr(mesh.crackMask.size_bytes()),
                   mesh.crackMask.data(), GL_STATIC_DRAW);
      glBindTexture(GL_TEXTURE_BUFFER, slot.crackTexture);
      glTexBuffer(GL_TEXTURE_BUFFER, GL_R8UI, slot.crack);
      glBindBuffer(GL_TEXTURE_BUFFER, 0);
    }
    stats.uploadedBytes += fullBytes;
    slot.vertices = uint32_t(vertices);
    slot.triangles = uint32_t(triangles);
    slot.hasScalar = hasScalar;
    slot.hasCrack = hasCrack;
    slot.hasUv = hasUv;
    slot.topologyVersion = mesh.topologyVersion;
  } else if (mesh.dirtyBegin < mesh.dirtyEnd) {
    const uint64_t count = mesh.dirtyEnd - mesh.dirtyBegin;
    auto subData = [&](GLuint buffer, const float* data, int components) {
      const uint64_t bytes = count * components * sizeof(float);
      glBindBuffer(GL_ARRAY_BUFFER, buffer);
      glBufferSubData(GL_ARRAY_BUFFER, GLintptr(mesh.dirtyBegin * components * sizeof(float)),
                      GLsizeiptr(bytes), data + uint64_t(mesh.dirtyBegin) * components);
      stats.uploadedBytes += bytes;
    };
    subData(slot.positions, mesh.positions.data(), 3);
    subData(slot.normals, mesh.normals.data(), 3);
    if (hasScalar) subData(slot.scalar, mesh.scalar.data(), 1);
  }
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  const std::string errors = drainGlErrors();
  if (!errors.empty()) return fail("uploading: ", errors);
  slot.uploaded = true;
  return {};
}

GLuint GlRenderer::textureFor(const std::shared_ptr<const Texture>& texture) {
  auto it = m_textures.find(texture.get());
  if (it != m_textures.end()) return it->second.second;
  GLuint name = 0;
  glGenTextures(1, &name);
  glBindTexture(GL_TEXTURE_2D, name);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  for (size_t level = 0; level < texture->levels.size(); ++level) {
    const Image& l = texture->levels[level];
    glTexImage2D(GL_TEXTURE_2D, GLint(level), GL_SRGB8_ALPHA8, l.width, l.height, 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, l.rgba.data());
  }
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, GLint(texture->levels.size()) - 1);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
  glBindTexture(GL_TEXTURE_2D, 0);
  m_textures.emplace(texture.get(), std::make_pair(texture, name));
  return name;
}

Result<FrameStats> GlRenderer::render(std::span<const MeshFrame> meshes, const Camera& camera,
                                      const FrameOptions& options, Image& out) {
  const auto start = std::chrono::steady_clock::now();
  Result<void> current = makeCurrent();
  if (!current) return current.error();
  drainGlErrors();  // errors of someone else's calls are not this frame's
  FrameStats stats;
  if (m_slots.size() < meshes.size()) m_slots.resize(meshes.size());
  for (size_t i = 0; i < meshes.size(); ++i) {
    Result<void> r = upload(m_slots[i], meshes[i], stats);
    if (!r) return fail("GL: mesh ", std::to_string(i), ": ", r.error().message);
  }

  // The image is drawn upside down (clip y negated, so the winding flips too): memory row 0 is
  // the top row, as in Vulkan's framebuffer. The MSAA sample pattern and the edge rule then fall
  // where the Vulkan back end's do, and edge pixels match the golden image within 1 instead of
  // differing by a sample's share (up to 35); readback needs no row flip.
  const glm::mat4 flipY(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1);
  const glm::mat4 viewProj =
      flipY *
      glm::perspective(glm::radians(camera.fovYDegrees), float(m_width) / float(m_height),
                       camera.nearPlane, camera.farPlane) *
      glm::lookAt(camera.eye, camera.target, camera.up);
  // The shadow pass, as the Vulkan back end's: the same light box, bias and map size; the
  // texture is cleared (all lit) when the frame has no shadows.
  const glm::mat4 light = shadowViewProj(meshes);
  const float texelWorld =
      2.0f / (glm::length(glm::vec3(light[0][0], light[1][0], light[2][0])) * float(kShadowSize));
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glBindFramebuffer(GL_FRAMEBUFFER, m_shadowFbo);
  glViewport(0, 0, kShadowSize, kShadowSize);
  glClearDepth(1.0);
  glClear(GL_DEPTH_BUFFER_BIT);
  if (options.shadows) {
    glDepthFunc(GL_LEQUAL);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(2.0f, 2.0f);
    glUseProgram(m_shadowProgram);
    glUniformMatrix4fv(m_uShadowLightViewProj, 1, GL_FALSE, glm::value_ptr(light));
    for (size_t i = 0; i < meshes.size(); ++i) {
      if (m_slots[i].triangles == 0 || !meshes[i].castsShadow) continue;
      glUniformMatrix4fv(m_uShadowModel, 1, GL_FALSE, glm::value_ptr(meshes[i].model));
      glBindVertexArray(m_slots[i].vao);
      glDrawElements(GL_TRIANGLES, GLsizei(3 * m_slots[i].triangles), GL_UNSIGNED_INT, nullptr);
    }
    glBindVertexArray(0);
    glDisable(GL_POLYGON_OFFSET_FILL);
  }

  glFrontFace(GL_CW);
  glBindFramebuffer(GL_FRAMEBUFFER, m_msaaFbo);
  glViewport(0, 0, m_width, m_height);
  glDisable(GL_FRAMEBUFFER_SRGB);
  glDepthFunc(GL_LESS);
  glClearColor(0.62f, 0.70f, 0.80f, 1.0f);
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glUseProgram(m_program);
  glUniformMatrix4fv(m_uViewProj, 1, GL_FALSE, glm::value_ptr(viewProj));
  glUniform3fv(m_uEye, 1, glm::value_ptr(camera.eye));
  glUniform1i(m_uCrackMask, 0);
  glUniform1i(m_uShadowMap, 1);
  glUniform1i(m_uTexture, 2);
  glUniformMatrix4fv(m_uLightViewProj, 1, GL_FALSE, glm::value_ptr(light));
  glUniform4f(m_uShadow, options.shadows ? 1.0f : 0.0f, 1.0f / float(kShadowSize),
              2.0f * texelWorld, 0.0f);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, m_shadowTexture);
  glActiveTexture(GL_TEXTURE0);
  glVertexAttrib1f(2, 0.0f);  // the scalar of meshes without one
  for (size_t i = 0; i < meshes.size(); ++i) {
    const MeshFrame& mesh = meshes[i];
    const Slot& slot = m_slots[i];
    if (slot.triangles == 0) continue;
    glUniformMatrix4fv(m_uModel, 1, GL_FALSE, glm::value_ptr(mesh.model));
    glUniform3fv(m_uCrackColour, 1, glm::value_ptr(mesh.crackColour));
    glUniform1i(m_uHasScalar, slot.hasScalar ? 1 : 0);
    glUniform1i(m_uHasCrack, slot.hasCrack ? 1 : 0);
    glUniform4f(m_uLook, mesh.crackLook.specular, mesh.crackLook.shininess, mesh.crackLook.grain,
                mesh.crackLook.metallic);
    glBindTexture(GL_TEXTURE_BUFFER, slot.crackTexture);
    glBindVertexArray(slot.vao);
    const DrawRange whole{0, slot.triangles, mesh.colour, slot.hasUv ? mesh.texture : nullptr};
    for (const DrawRange& r :
         mesh.ranges.empty() ? std::span<const DrawRange>(&whole, 1) : mesh.ranges) {
      if (r.triangleCount == 0) continue;
      glUniform3fv(m_uColour, 1, glm::value_ptr(r.colour));
      glUniform4f(m_uGround, mesh.gridSpacing, r.texture ? 1.0f : 0.0f, float(r.firstTriangle),
                  0.0f);
      if (r.texture) {
        glActiveTexture(GL_TEXTURE2);
        glBindTexture(GL_TEXTURE_2D, textureFor(r.texture));
        glActiveTexture(GL_TEXTURE0);
      }
      glDrawElements(GL_TRIANGLES, GLsizei(3 * r.triangleCount), GL_UNSIGNED_INT,
                     reinterpret_cast<const void*>(uintptr_t(r.firstTriangle) * 12));
    }
  }
  glBindVertexArray(0);
  glBindTexture(GL_TEXTURE_BUFFER, 0);
  glActiveTexture(GL_TEXTURE2);
  glBindTexture(GL_TEXTURE_2D, 0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, 0);
  glActiveTexture(GL_TEXTURE0);
  std::string errors = drainGlErrors();
  if (!errors.empty()) return fail("GL: drawing: ", errors);

  glBindFramebuffer(GL_READ_FRAMEBUFFER, m_msaaFbo);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, m_resolveFbo);
  glBlitFramebuffer(0, 0, m_width, m_height, 0, 0, m_width, m_height, GL_COLOR_BUFFER_BIT,
                    GL_NEAREST);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, m_resolveFbo);
  out.width = m_width;
  out.height = m_height;
  out.rgba.resize(size_t(m_width) * size_t(m_height) * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, m_width, m_height, GL_RGBA, GL_UNSIGNED_BYTE, out.rgba.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  errors = drainGlErrors();
  if (!errors.empty()) return fail("GL: resolving and reading back: ", errors);
  drawOverlay(out, options.overlay);
  stats.renderMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace

Result<std::unique_ptr<Renderer>> createGlRenderer(const RendererOptions& options) {
  if (options.width <= 0 || options.height <= 0 || options.width > 8192 || options.height > 8192)
    return fail("GL: size ", std::to_string(options.width), "x", std::to_string(options.height),
                " is outside 1x1 .. 8192x8192");
  auto renderer = std::make_unique<GlRenderer>();
  Result<void> r = renderer->init(options);
  if (!r) return r.error();
  return std::unique_ptr<Renderer>(std::move(renderer));
}

}  // namespace gf::demo
