// loadScene: any file assimp reads, flattened into one world-space triangle mesh.
//
// The node hierarchy is walked here rather than with aiProcess_PreTransformVertices: that
// step multiplies in single precision, and far from the origin (city tiles, CAD parts
// placed in millimetres) the float rounding of composed transforms becomes visible at
// R = 2^18. Node matrices are converted to double and composed in double; every vertex
// of every mesh instance is transformed once, in double.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <assimp/DefaultIOSystem.h>
#include <assimp/GltfMaterial.h>
#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "cpvs/scene/import.h"
#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"

namespace cpvs {
namespace {

/// Row-major affine transform in double, the same layout as aiMatrix4x4 (a1..a4 is the
/// first row; the translation is the fourth column).
struct Mat4d {
  std::array<double, 16> m{};

  static Mat4d identity() {
    Mat4d r;
    r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1.0;
    return r;
  }

  static Mat4d fromAssimp(const aiMatrix4x4& a) {
    Mat4d r;
    for (int i = 0; i < 4; ++i)  // a[i] is row i
      for (int j = 0; j < 4; ++j) r.m[4 * i + j] = static_cast<double>(a[i][j]);
    return r;
  }

  Mat4d operator*(const Mat4d& o) const {
    Mat4d r;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        double s = 0;
        for (int k = 0; k < 4; ++k) s += m[4 * i + k] * o.m[4 * k + j];
        r.m[4 * i + j] = s;
      }
    return r;
  }

  /// Determinant of the linear part (upper-left 3x3).
  double determinant3() const {
    return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
           m[2] * (m[4] * m[9] - m[5] * m[8]);
  }

  /// Transforms a point. Node transforms are affine, so the bottom row is ignored
  /// rather than dividing by w (a projective node matrix is not a meaningful scene).
  Vec3 transformPoint(double x, double y, double z) const {
    return {m[0] * x + m[1] * y + m[2] * z + m[3], m[4] * x + m[5] * y + m[6] * z + m[7],
            m[8] * x + m[9] * y + m[10] * z + m[11]};
  }
};

std::string formatVec(const Vec3& v) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "(%g, %g, %g)", v.x, v.y, v.z);
  return buf;
}

/// "vertex 17 of mesh 2 'hull'", for error messages.
std::string describeVertex(const aiMesh& mesh, unsigned meshIndex, unsigned vertex) {
  std::string s = "vertex " + std::to_string(vertex) + " of mesh " + std::to_string(meshIndex);
  if (mesh.mName.length > 0) s += std::string(" '") + mesh.mName.C_Str() + "'";
  return s;
}

/// Appends one instance of `mesh` under `world` to `scene`: every vertex (so that indices
/// stay valid) and every face with exactly three indices. Throws InputError for a
/// vertex that is not finite in world space.
/// The constant transmittance of a material (seed 003 §3.4), per channel: the uncovered
/// share 1 - alpha passes whole, the covered share alpha passes its transmission factor
/// (glTF KHR_materials_transmission) tinted by the base colour. Alpha follows glTF's
/// alphaMode where the file has one (OPAQUE: 1, MASK: 0 or 1 by the cutoff, BLEND: the
/// base colour's alpha), otherwise the material's opacity where the format's is
/// unambiguous (`readOpacity`: an OBJ's `d`, an IFC surface style's transparency). COLLADA
/// and FBX files carry opacities their exporters invert (3ds Max's COLLADA writes
/// `transparency 0` for opaque teapots): read there, whole scenes would cast nothing, so
/// those formats bake opaque. Textures are not read: a card of leaves whose cut-out lives
/// in a texture casts by its factors alone.
std::array<float, 3> transmittanceOf(const aiMaterial* mat, bool readOpacity) {
  std::array<float, 3> out{0, 0, 0};
  if (mat == nullptr) return out;
  aiColor4D base(1, 1, 1, 1);
  if (mat->Get(AI_MATKEY_BASE_COLOR, base) != AI_SUCCESS) mat->Get(AI_MATKEY_COLOR_DIFFUSE, base);
  auto unit = [](float v, float fallback) { return std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : fallback; };
  float alpha = 1;
  aiString mode;
  if (mat->Get(AI_MATKEY_GLTF_ALPHAMODE, mode) == AI_SUCCESS) {
    const std::string m = mode.C_Str();
    float cutoff = 0.5f;
    mat->Get(AI_MATKEY_GLTF_ALPHACUTOFF, cutoff);
    if (m == "BLEND") alpha = unit(base.a, 1);
    else if (m == "MASK") alpha = unit(base.a, 1) < cutoff ? 0.0f : 1.0f;
  } else if (readOpacity) {
    float opacity = 1;
    if (mat->Get(AI_MATKEY_OPACITY, opacity) == AI_SUCCESS) alpha = unit(opacity, 1);
  }
  float transmission = 0;
  mat->Get(AI_MATKEY_TRANSMISSION_FACTOR, transmission);
  transmission = unit(transmission, 0);
  const float tint[3] = {unit(base.r, 1), unit(base.g, 1), unit(base.b, 1)};
  for (int c = 0; c < 3; ++c) {
    out[c] = unit((1 - alpha) + alpha * transmission * tint[c], 0);
    if (out[c] < kMinTransmittance) out[c] = 0;
  }
  return out;
}

void appendInstance(const std::string& path, const aiMesh& mesh, unsigned meshIndex, const Mat4d& world,
                    const std::string& nodeName, const aiMaterial* material, bool readOpacity, Scene& scene) {
  const size_t base = scene.positions.size();
  const size_t firstTriangle = scene.triangleCount();
  if (firstTriangle + mesh.mNumFaces > std::numeric_limits<uint32_t>::max())
    throw InputError(path + ": more than 2^32 triangles after instancing");
  if (base + mesh.mNumVertices > std::numeric_limits<uint32_t>::max())
    throw InputError(path + ": more than 2^32 vertices after instancing");
  scene.positions.reserve(base + mesh.mNumVertices);
  for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
    const aiVector3D& p = mesh.mVertices[v];
    const Vec3 w = world.transformPoint(p.x, p.y, p.z);
    if (!isFinite(w)) {
      throw InputError(path + ": " + describeVertex(mesh, meshIndex, v) +
                       " is not finite in world space " + formatVec(w));
    }
    scene.positions.push_back(w);
  }
  // A mirroring transform (negative determinant) reverses the winding of what it places;
  // the front side stays the front side (glTF states this rule, and it is the only one
  // under which a mirrored closed mesh stays outward-facing), so such instances are
  // written with two corners swapped.
  const bool mirrored = world.determinant3() < 0;
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    if (face.mNumIndices != 3) continue;  // points and lines carry no shadow
    for (int c = 0; c < 3; ++c) {
      const unsigned idx = face.mIndices[mirrored && c > 0 ? 3 - c : c];
      // assimp validates only when asked to; an out-of-range index is a broken file.
      if (idx >= mesh.mNumVertices)
        throw InputError(path + ": face " + std::to_string(f) + " of mesh " +
                         std::to_string(meshIndex) + " indexes vertex " + std::to_string(idx) +
                         " of " + std::to_string(mesh.mNumVertices));
      scene.indices.push_back(static_cast<uint32_t>(base + idx));
    }
  }
  scene.meshes.push_back({nodeName, mesh.mName.C_Str(), material ? material->GetName().C_Str() : "",
                          uint32_t(firstTriangle), uint32_t(scene.triangleCount() - firstTriangle),
                          transmittanceOf(material, readOpacity)});
}

SceneLight lightOf(const aiLight& l, const Mat4d& world) {
  SceneLight out;
  out.name = l.mName.C_Str();
  switch (l.mType) {
    case aiLightSource_DIRECTIONAL: out.type = SceneLight::Type::Directional; break;
    case aiLightSource_POINT: out.type = SceneLight::Type::Point; break;
    case aiLightSource_SPOT: out.type = SceneLight::Type::Spot; break;
    case aiLightSource_AREA: out.type = SceneLight::Type::Area; break;
    case aiLightSource_AMBIENT: out.type = SceneLight::Type::Ambient; break;
    default: out.type = SceneLight::Type::Unknown; break;
  }
  out.position = world.transformPoint(l.mPosition.x, l.mPosition.y, l.mPosition.z);
  const Vec3 d = world.transformPoint(l.mDirection.x, l.mDirection.y, l.mDirection.z) - world.transformPoint(0, 0, 0);
  out.direction = length(d) > 0 && isFinite(d) ? normalize(d) : Vec3{};
  out.color = {l.mColorDiffuse.r, l.mColorDiffuse.g, l.mColorDiffuse.b};
  out.innerConeDeg = double(l.mAngleInnerCone) * 180.0 / M_PI;
  out.outerConeDeg = double(l.mAngleOuterCone) * 180.0 / M_PI;
  if (l.mType == aiLightSource_AREA) {
    // The rectangle: mSize.y along mUp, mSize.x across it, so that U x V is the light's
    // direction; placed (scaled, turned) by the node as its position is.
    const aiVector3D across = l.mDirection ^ l.mUp;
    auto vector = [&](const aiVector3D& v, double size) {
      const Vec3 w = world.transformPoint(v.x * size, v.y * size, v.z * size) - world.transformPoint(0, 0, 0);
      return isFinite(w) ? w : Vec3{};
    };
    out.edgeU = vector(l.mUp, l.mSize.y);
    out.edgeV = vector(across, l.mSize.x);
  }
  return out;
}

/// Opens one file, for reading, and nothing else; remembers what else was asked for.
class OneFileIOSystem final : public Assimp::DefaultIOSystem {
 public:
  explicit OneFileIOSystem(const std::string& path) : allowed_(canonical(path)) {}
  bool Exists(const char* file) const override { return canonical(file) == allowed_; }
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    if (canonical(file) != allowed_ || std::string(mode).find_first_of("wa+") != std::string::npos) {
      if (refused_.empty()) refused_ = file;
      return nullptr;
    }
    return Assimp::DefaultIOSystem::Open(file, mode);
  }
  const std::string& refused() const { return refused_; }

 private:
  static std::string canonical(const std::string& file) {
    std::error_code ec;
    const std::filesystem::path p = std::filesystem::weakly_canonical(std::filesystem::absolute(file, ec), ec);
    return ec ? std::string() : p.string();
  }
  std::string allowed_;
  std::string refused_;
};

}  // namespace

Scene loadScene(const std::string& path, SceneStats* stats, const ImportOptions& options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path + ": no such file");

  Assimp::Importer importer;
  OneFileIOSystem* oneFile = nullptr;
  if (options.selfContained) importer.SetIOHandler(oneFile = new OneFileIOSystem(path));  // the importer owns it
  // Points and lines are removed by SortByPType rather than skipped later so that the
  // remaining meshes are pure triangle meshes.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* ai = importer.ReadFile(path, aiProcess_Triangulate | aiProcess_SortByPType);
  if (ai == nullptr) {
    if (oneFile && !oneFile->refused().empty())
      throw InputError(path + ": it refers to another file ('" + std::filesystem::path(oneFile->refused()).filename().string() +
                       "'): external references are not allowed; send one self-contained file (for glTF, a .glb "
                       "or buffers embedded as data: URIs)");
    throw InputError(path + ": assimp cannot read it: " + importer.GetErrorString());
  }
  // Positions are checked before JoinIdenticalVertices: that step compares positions
  // with NaN-unaware ordering and was seen to merge a NaN vertex silently into a finite
  // one (an OBJ line `v nan 0 0` became (0, 0, 0)).
  for (unsigned m = 0; m < ai->mNumMeshes; ++m) {
    const aiMesh& mesh = *ai->mMeshes[m];
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const aiVector3D& p = mesh.mVertices[v];
      const Vec3 local{p.x, p.y, p.z};
      if (!isFinite(local))
        throw InputError(path + ": " + describeVertex(mesh, m, v) + " is not finite " + formatVec(local));
    }
  }
  ai = importer.ApplyPostProcessing(aiProcess_JoinIdenticalVertices);
  if (ai == nullptr) {
    throw InputError(path + ": assimp failed to post-process it: " + importer.GetErrorString());
  }

  Scene scene;
  scene.name = std::filesystem::path(path).filename().string();
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = char(std::tolower(static_cast<unsigned char>(c)));
  const bool readOpacity = extension == ".obj" || extension == ".ifc";

  if (ai->mRootNode != nullptr) {
    // Explicit stack: CAD files nest deeply and a recursion depth set by the file is
    // not worth the risk.
    std::vector<std::pair<const aiNode*, Mat4d>> stack;
    stack.emplace_back(ai->mRootNode, Mat4d::fromAssimp(ai->mRootNode->mTransformation));
    while (!stack.empty()) {
      auto [node, world] = stack.back();
      stack.pop_back();
      // A light is placed by the node of its name.
      for (unsigned l = 0; l < ai->mNumLights; ++l)
        if (ai->mLights[l] != nullptr && ai->mLights[l]->mName == node->mName) scene.lights.push_back(lightOf(*ai->mLights[l], world));
      for (unsigned i = 0; node->mMeshes != nullptr && i < node->mNumMeshes; ++i) {
        const unsigned meshIndex = node->mMeshes[i];
        if (meshIndex >= ai->mNumMeshes || ai->mMeshes[meshIndex] == nullptr)
          throw InputError(path + ": node '" + node->mName.C_Str() + "' references missing mesh " +
                           std::to_string(meshIndex));
        const aiMesh& mesh = *ai->mMeshes[meshIndex];
        const aiMaterial* material = mesh.mMaterialIndex < ai->mNumMaterials ? ai->mMaterials[mesh.mMaterialIndex] : nullptr;
        appendInstance(path, mesh, meshIndex, world, node->mName.C_Str(), material, readOpacity, scene);
      }
      // Children pushed in reverse so that they are visited in file order, which keeps
      // vertex order (and so the scene hash) independent of the stack discipline.
      // Some importers leave child slots empty (assimp's RAW reader: a null child per
      // object without faces): nothing hangs there.
      for (unsigned c = node->mChildren == nullptr ? 0 : node->mNumChildren; c-- > 0;) {
        const aiNode* child = node->mChildren[c];
        if (child != nullptr) stack.emplace_back(child, world * Mat4d::fromAssimp(child->mTransformation));
      }
    }
  }

  if (scene.indices.empty()) throw InputError(path + ": holds no triangles");
  // Materials with a volume (glTF KHR_materials_volume, thickness above 0): media.
  for (unsigned m = 0; m < ai->mNumMaterials; ++m) {
    const aiMaterial* mat = ai->mMaterials[m];
    float thickness = 0;
    if (mat == nullptr || mat->Get(AI_MATKEY_VOLUME_THICKNESS_FACTOR, thickness) != AI_SUCCESS || !(thickness > 0)) continue;
    SceneMedium medium;
    medium.material = mat->GetName().C_Str();
    float distance = 0;
    aiColor3D colour(1, 1, 1);
    mat->Get(AI_MATKEY_VOLUME_ATTENUATION_COLOR, colour);
    // glTF's default distance is infinite: no absorption.
    if (mat->Get(AI_MATKEY_VOLUME_ATTENUATION_DISTANCE, distance) == AI_SUCCESS && distance > 0 && std::isfinite(distance)) {
      double sum = 0;
      for (float c : {colour.r, colour.g, colour.b}) sum += -std::log(std::clamp(double(c), 1e-6, 1.0)) / double(distance);
      medium.absorption = sum / 3;
    }
    scene.media.push_back(std::move(medium));
  }

  SceneStats s = finalizeScene(scene);
  if (scene.indices.empty()) throw InputError(path + ": holds no triangles (all have zero area)");
  if (stats != nullptr) *stats = s;
  return scene;
}

}  // namespace cpvs
