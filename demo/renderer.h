// The demo's off-screen renderer: draws surface streams (World::surface, SurfaceView) and
// rigid shapes into an image, through Vulkan (any device the loader finds: a GPU, or Mesa's
// lavapipe on the CPU) or an OpenGL context from EGL when no Vulkan device exists. No window,
// no display. Both back ends draw the same scene with the same shading so a golden image holds
// for either within a small tolerance.
#pragma once

#include <graphfrac/status.h>

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace gf::demo {

/// An 8-bit RGBA image, rows top to bottom.
struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;  ///< 4 * width * height bytes
};

enum class RendererKind { Auto, Vulkan, Gl };
/// "auto", "vulkan" or "gl" (the command lines' --renderer); false for anything else.
bool parseRendererKind(std::string_view name, RendererKind& kind);

struct RendererOptions {
  RendererKind kind = RendererKind::Auto;  ///< Auto: Vulkan if a device exists, else GL (EGL)
  int width = 640, height = 360;
  int samples = 4;          ///< MSAA samples (clamped to what the device supports)
  bool validation = false;  ///< Vulkan: enable VK_LAYER_KHRONOS_validation (error if missing)
};

/// How crack faces of a mesh are drawn (flat-shaded facets either way). The defaults are the
/// plain surface model's, so a mesh without a look is shaded as before.
struct CrackLook {
  float specular = 0.12f;   ///< Strength of the highlight.
  float shininess = 48.0f;  ///< Blinn-Phong exponent: low = rough (crumb), high = polished (glass).
  float grain = 0.0f;       ///< Depth of pore-sized mottling of the colour (bread crumb), 0..1.
  float metallic = 0.0f;    ///< 1: the highlight takes the surface colour (steel).
};

/// The look of a scene's "interior" ("plain", "glass", "crumb", "steel"); plain for others.
CrackLook crackLook(const std::string& interior);

struct Camera {
  glm::vec3 eye{1.5f, 1.0f, 1.5f};
  glm::vec3 target{0.0f, 0.2f, 0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fovYDegrees = 45.0f;
  float nearPlane = 0.01f, farPlane = 50.0f;
};

/// A colour texture: sRGB-encoded 8-bit RGBA as image files hold it (the shaders sample it as
/// linear light), level 0 the image and each next level half as large down to 1x1 (a box filter
/// in linear light). Renderers keep one GPU copy per Texture object for as long as they live.
struct Texture {
  std::vector<Image> levels;
};
/// The texture of an image with its mip levels; an error for an empty or inconsistent image.
Result<std::shared_ptr<const Texture>> makeTexture(Image image);
/// Decodes an image file (PNG, JPEG, TGA, BMP, ... through stb_image) into a texture; the error
/// names the file and the reason.
Result<std::shared_ptr<const Texture>> loadTexture(const std::string& path);

/// A run of a mesh's triangles drawn in a material of its own (MeshFrame::ranges).
struct DrawRange {
  uint32_t firstTriangle = 0, triangleCount = 0;
  glm::vec3 colour{0.8f, 0.8f, 0.8f};      ///< linear RGB, in place of MeshFrame::colour
  std::shared_ptr<const Texture> texture;  ///< multiplied into colour (needs uvs); null: none
};
/// Triangles a range may start at: its offset reaches the shaders as an exact float.
inline constexpr uint32_t kMaxRangeStart = 1u << 24;

/// One mesh this frame. Mesh i of a frame keeps its GPU buffers in slot i across frames: the
/// renderer re-uploads vertices and indices when topologyVersion (or the size) changes, and
/// otherwise only the vertices in [dirtyBegin, dirtyEnd). The spans are read during render()
/// only.
struct MeshFrame {
  std::span<const float> positions;    ///< 3 per vertex, in model space
  std::span<const float> normals;      ///< 3 per vertex, unit
  std::span<const uint32_t> indices;   ///< 3 per triangle, counter-clockwise from outside
  std::span<const uint8_t> crackMask;  ///< per triangle, 1 = crack face; empty = none
  std::span<const float> scalar;       ///< per vertex in [0, 1] for the colour map; empty = off
  /// 2 per vertex: texture coordinates, u right and v up from the image's bottom left (OpenGL's
  /// convention, which assimp gives); read only with a texture, and only on a full upload (they
  /// are rest-frame data, fixed between topology changes).
  std::span<const float> uvs;
  /// Multiplied into `colour` (or the colour map) on the original surface; crack faces keep
  /// crackColour. Needs uvs; null: drawn in the plain colour, exactly as without textures.
  std::shared_ptr<const Texture> texture;
  /// Non-empty: the mesh is drawn as these runs of its triangles, each in its own colour and
  /// texture (crack faces keep crackColour), in place of `colour` and `texture`; triangles in no
  /// range are not drawn (the shadow pass draws them all). Empty: drawn whole, as before.
  std::span<const DrawRange> ranges;
  uint64_t topologyVersion = 0;
  uint32_t dirtyBegin = 0, dirtyEnd = 0;
  glm::mat4 model{1.0f};                      ///< model to world
  glm::vec3 colour{0.8f, 0.8f, 0.8f};         ///< linear RGB of the original surface
  glm::vec3 crackColour{0.95f, 0.55f, 0.3f};  ///< linear RGB of crack faces
  CrackLook crackLook;
  float gridSpacing = 0;    ///< > 0: a grid and checker of this cell size [m] on x-z (ground)
  bool castsShadow = true;  ///< drawn into the shadow map (FrameOptions::shadows)
};

/// Per-frame extras of render().
struct FrameOptions {
  /// A shadow map from the key light (a depth pass over the casting meshes) darkens what lies
  /// behind them; off, the light reaches everything (the plain shading model).
  bool shadows = false;
  std::vector<std::string> overlay;  ///< Text lines drawn over the top left of the frame.
};

/// What one render() cost.
struct FrameStats {
  uint64_t uploadedBytes = 0;  ///< bytes copied to the device this frame (vertices + indices;
                               ///< textures, uploaded once, are not counted)
  uint64_t surfaceBytes = 0;   ///< bytes a full re-upload of every mesh would have copied
  double renderMs = 0;         ///< upload + draw + readback, wall clock
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  /// Back end and device, e.g. "Vulkan, llvmpipe (LLVM 15.0.6, 256 bits), CPU".
  virtual const std::string& description() const = 0;
  /// Draws the meshes over a ground-free sky-coloured background, lit by a fixed directional
  /// light plus ambient, and reads the resolved image back into `out` (resized to fit).
  virtual Result<FrameStats> render(std::span<const MeshFrame> meshes, const Camera& camera,
                                    const FrameOptions& options, Image& out) = 0;
  /// render() without shadows or overlay.
  Result<FrameStats> render(std::span<const MeshFrame> meshes, const Camera& camera, Image& out) {
    return render(meshes, camera, FrameOptions{}, out);
  }
  /// Errors and warnings the Vulkan validation layers reported so far (RendererOptions::
  /// validation); always empty for GL.
  virtual std::vector<std::string> validationMessages() const { return {}; }
};

/// Creates the renderer `options.kind` asks for; Auto tries Vulkan, then GL through EGL. The
/// error names what was tried and why each failed.
Result<std::unique_ptr<Renderer>> createRenderer(const RendererOptions& options);

// Back ends (each compiled only when its dependency was found; otherwise these return an error
// saying it was not built).
Result<std::unique_ptr<Renderer>> createVulkanRenderer(const RendererOptions& options);
Result<std::unique_ptr<Renderer>> createGlRenderer(const RendererOptions& options);

/// Unit vector towards the key light, the one the shaders light with.
inline constexpr glm::vec3 kKeyLight{0.4f, 1.0f, 0.3f};  // normalised where it is used
/// The key light's view-projection (GL clip conventions) for the shadow map: an orthographic
/// box along the light around the bounding sphere of the casting meshes (identity if none).
glm::mat4 shadowViewProj(std::span<const MeshFrame> meshes);

/// Draws `lines` of text over the top left of `image` (a dark translucent panel with white
/// text, 2x-scaled stb_easy_font glyphs; smaller for images under 480 pixels wide). Does
/// nothing where the renderer was built without stb (the demo says so).
void drawOverlay(Image& image, std::span<const std::string> lines);
/// True when drawOverlay draws (stb_easy_font was found at configure).
bool overlayAvailable();

/// Frames side by side in rows of `columns`, each scaled (box filter) to `cellWidth` pixels
/// wide, with a 2-pixel dark gap; the images must all have one size.
Result<Image> contactSheet(std::span<const Image> frames, int columns, int cellWidth);

/// Writes an RGBA image as PNG; the error names the path and the reason.
Result<void> writePng(const std::string& path, const Image& image);
/// Reads a PNG (any colour type, converted to 8-bit RGBA).
Result<Image> readPng(const std::string& path);

/// How two images of the same size differ.
struct ImageDiff {
  double meanAbs = 0;       ///< mean absolute difference per channel, in 0..255
  int maxAbs = 0;           ///< largest per-channel difference
  double fractionOver = 0;  ///< fraction of pixels with some channel differing by > threshold
};
/// Compares RGB channels; error when the sizes differ.
Result<ImageDiff> compareImages(const Image& a, const Image& b, int threshold);

}  // namespace gf::demo
