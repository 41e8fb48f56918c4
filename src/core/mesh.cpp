/// @file mesh.cpp
/// Triangle meshes: loading (assimp), welding, validation and vertex normals.
#include "deformable_flsm/core/mesh.h"

#include <Eigen/Geometry>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <system_error>
#include <unordered_map>

namespace deformable_flsm {
namespace {

/// Post-processing asked of assimp. PreTransformVertices bakes every node transform into the
/// vertex positions (so a scene made of several placed meshes comes out as it looks), and
/// SortByPType splits mixed meshes so that point and line primitives can be skipped by type.
constexpr unsigned int kImportFlags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                      aiProcess_PreTransformVertices | aiProcess_SortByPType;

/// Key for exact-position welding. Adding 0.0 maps -0.0 to +0.0, so that the two zeros (which
/// compare equal) also hash and compare equal bitwise.
struct PositionKey {
  std::array<std::uint64_t, 3> bits;

  explicit PositionKey(const Eigen::Vector3d& p) {
    for (int a = 0; a < 3; ++a) {
      const double v = p[a] + 0.0;
      std::memcpy(&bits[static_cast<std::size_t>(a)], &v, sizeof v);
    }
  }
  bool operator==(const PositionKey& other) const { return bits == other.bits; }
};

struct PositionKeyHash {
  std::size_t operator()(const PositionKey& key) const {
    // boost::hash_combine mixing of the three bit patterns.
    std::size_t h = 0;
    for (const std::uint64_t b : key.bits) {
      h ^= std::hash<std::uint64_t>{}(b) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    }
    return h;
  }
};

/// Throws MeshError if a triangle refers to a vertex that does not exist; `context` starts the
/// message.
void checkIndices(const std::vector<std::array<std::uint32_t, 3>>& triangles,
                  std::size_t vertexCount, const std::string& context) {
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (const std::uint32_t index : triangles[t]) {
      if (index >= vertexCount) {
        std::ostringstream message;
        message << context << ": triangle " << t << " refers to vertex " << index
                << " but the mesh has only " << vertexCount
                << " vertices; fix the face indices of the mesh";
        throw MeshError(message.str());
      }
    }
  }
}

}  // namespace

Eigen::Vector3d TriMesh::boundsMin() const {
  if (vertices.empty()) return Eigen::Vector3d::Zero();
  Eigen::Vector3d lo = vertices.front();
  for (const Eigen::Vector3d& v : vertices) lo = lo.cwiseMin(v);
  return lo;
}

Eigen::Vector3d TriMesh::boundsMax() const {
  if (vertices.empty()) return Eigen::Vector3d::Zero();
  Eigen::Vector3d hi = vertices.front();
  for (const Eigen::Vector3d& v : vertices) hi = hi.cwiseMax(v);
  return hi;
}

namespace {
/// glmark2's ".jobj" (its jellyfish): "v x y z" vertex lines and "i n" index lines, three per
/// triangle; assimp does not know it.
bool isJobj(const std::string& path);
TriMesh readJobj(const std::string& path);
/// Every other format, through assimp.
TriMesh readWithAssimp(const std::string& path);
}  // namespace

TriMesh loadMesh(const std::string& path, double scale) {
  if (!std::isfinite(scale) || scale <= 0.0) {
    std::ostringstream message;
    message << "mesh file '" << path << "': scale must be a finite number > 0, got " << scale;
    throw MeshError(message.str());
  }
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw MeshError("mesh file '" + path + "' does not exist; check the path (relative paths are "
                    "resolved from the current working directory)");
  }
  if (std::filesystem::is_directory(path, ec)) {
    throw MeshError("mesh file '" + path + "' is a directory, not a mesh file");
  }

  TriMesh mesh = isJobj(path) ? readJobj(path) : readWithAssimp(path);

  // Validate before welding too: a mesh collapsed to a point would otherwise lose all its
  // triangles to welding and be reported as having none, which hides the real problem.
  validateMesh(mesh, path);
  weldVertices(mesh);
  if (mesh.triangles.empty()) {
    throw MeshError("mesh file '" + path +
                    "': every triangle is degenerate (two corners at the same position); repair "
                    "or re-export the mesh");
  }
  for (Eigen::Vector3d& v : mesh.vertices) v *= scale;
  // Scaling can overflow to infinity or underflow to a point.
  validateMesh(mesh, path);
  return mesh;
}

namespace {

bool isJobj(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".jobj";
}

TriMesh readJobj(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw MeshError("cannot open mesh file '" + path + "'");
  TriMesh mesh;
  std::vector<std::uint32_t> indices;
  std::string line, tag;
  std::size_t lineNumber = 0;
  while (std::getline(in, line)) {
    ++lineNumber;
    std::istringstream fields(line);
    if (!(fields >> tag)) continue;
    if (tag == "v") {
      Eigen::Vector3d p;
      if (!(fields >> p.x() >> p.y() >> p.z()))
        throw MeshError("mesh file '" + path + "', line " + std::to_string(lineNumber) +
                        ": a vertex needs three numbers");
      mesh.vertices.push_back(p);
    } else if (tag == "i") {
      long long index = -1;
      if (!(fields >> index) || index < 0 || index > std::numeric_limits<std::uint32_t>::max())
        throw MeshError("mesh file '" + path + "', line " + std::to_string(lineNumber) +
                        ": an index must be a number >= 0");
      indices.push_back(static_cast<std::uint32_t>(index));
    }  // vn, vt, vc: normals, texture coordinates and colours are not needed
  }
  if (indices.size() % 3 != 0)
    throw MeshError("mesh file '" + path + "': " + std::to_string(indices.size()) +
                    " indices, not a whole number of triangles");
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3)
    mesh.triangles.push_back({indices[t], indices[t + 1], indices[t + 2]});
  if (mesh.triangles.empty())
    throw MeshError("mesh file '" + path + "' has no triangles ('i' index lines)");
  return mesh;
}

TriMesh readWithAssimp(const std::string& path) {
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, kImportFlags);
  if (scene == nullptr || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0) {
    std::string reason = importer.GetErrorString();
    // assimp's messages end in a full stop of their own; drop it before our sentence continues.
    while (!reason.empty() && (reason.back() == '.' || std::isspace(static_cast<unsigned char>(
                                                           reason.back())))) {
      reason.pop_back();
    }
    throw MeshError("cannot read mesh file '" + path + "': " + reason +
                    "; check that it is a valid mesh in a format assimp reads (OBJ, STL, PLY, "
                    "DAE, 3DS, OFF, ...)");
  }

  TriMesh mesh;
  for (unsigned int m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* source = scene->mMeshes[m];
    // Points and lines have no volume to simulate; SortByPType has put them in meshes of their own.
    if ((source->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) == 0) continue;
    const std::size_t base = mesh.vertices.size();
    for (unsigned int v = 0; v < source->mNumVertices; ++v) {
      const aiVector3D& p = source->mVertices[v];
      mesh.vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned int f = 0; f < source->mNumFaces; ++f) {
      const aiFace& face = source->mFaces[f];
      if (face.mNumIndices != 3) continue;
      mesh.triangles.push_back({static_cast<std::uint32_t>(base + face.mIndices[0]),
                                static_cast<std::uint32_t>(base + face.mIndices[1]),
                                static_cast<std::uint32_t>(base + face.mIndices[2])});
    }
  }
  if (mesh.triangles.empty()) {
    throw MeshError("mesh file '" + path +
                    "' has no triangles (only points, lines or nothing); export the surface as a "
                    "triangle or polygon mesh");
  }
  return mesh;
}

}  // namespace

void validateMesh(const TriMesh& mesh, const std::string& name) {
  if (mesh.triangles.empty()) {
    throw MeshError("mesh '" + name + "' has no triangles; a closed triangle surface is needed");
  }
  checkIndices(mesh.triangles, mesh.vertices.size(), "mesh '" + name + "'");
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    if (!mesh.vertices[v].allFinite()) {
      std::ostringstream message;
      message << "mesh '" << name << "' has non-finite coordinates (NaN or infinity) at vertex "
              << v << "; repair or re-export the mesh";
      throw MeshError(message.str());
    }
  }
  const Eigen::Vector3d extent = mesh.boundsMax() - mesh.boundsMin();
  if (!(extent.maxCoeff() > 0.0)) {
    throw MeshError("mesh '" + name +
                    "' has zero extent (degenerate: all vertices lie on a single point); check "
                    "the file and the scale");
  }
}

std::size_t weldVertices(TriMesh& mesh) {
  checkIndices(mesh.triangles, mesh.vertices.size(), "weldVertices");
  std::unordered_map<PositionKey, std::uint32_t, PositionKeyHash> firstIndex;
  firstIndex.reserve(mesh.vertices.size());
  std::vector<std::uint32_t> remap(mesh.vertices.size());
  std::vector<Eigen::Vector3d> welded;
  welded.reserve(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const auto [it, inserted] =
        firstIndex.emplace(PositionKey(mesh.vertices[v]), static_cast<std::uint32_t>(welded.size()));
    if (inserted) welded.push_back(mesh.vertices[v]);
    remap[v] = it->second;
  }
  const std::size_t removed = mesh.vertices.size() - welded.size();
  mesh.vertices = std::move(welded);

  std::size_t kept = 0;
  for (const std::array<std::uint32_t, 3>& t : mesh.triangles) {
    const std::array<std::uint32_t, 3> r = {remap[t[0]], remap[t[1]], remap[t[2]]};
    if (r[0] == r[1] || r[1] == r[2] || r[2] == r[0]) continue;
    mesh.triangles[kept++] = r;
  }
  mesh.triangles.resize(kept);
  return removed;
}

std::size_t countBoundaryEdges(const TriMesh& mesh) {
  // Each undirected edge as a 64-bit key (smaller index high); sorting groups the uses of an edge.
  std::vector<std::uint64_t> edges;
  edges.reserve(3 * mesh.triangles.size());
  for (const std::array<std::uint32_t, 3>& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) {
      const std::uint64_t a = t[static_cast<std::size_t>(c)];
      const std::uint64_t b = t[static_cast<std::size_t>((c + 1) % 3)];
      edges.push_back((std::min(a, b) << 32) | std::max(a, b));
    }
  }
  std::sort(edges.begin(), edges.end());
  std::size_t boundary = 0;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i != 2) ++boundary;
    i = j;
  }
  return boundary;
}

void computeVertexNormals(const std::vector<Eigen::Vector3d>& positions,
                          const std::vector<std::array<std::uint32_t, 3>>& triangles,
                          std::vector<Eigen::Vector3d>& normals) {
  checkIndices(triangles, positions.size(), "computeVertexNormals");
  normals.assign(positions.size(), Eigen::Vector3d::Zero());
  for (const std::array<std::uint32_t, 3>& t : triangles) {
    const Eigen::Vector3d& a = positions[t[0]];
    const Eigen::Vector3d& b = positions[t[1]];
    const Eigen::Vector3d& c = positions[t[2]];
    // |(b - a) x (c - a)| is twice the triangle's area, so summing the raw cross products
    // weights each face by its area.
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (!n.allFinite()) continue;
    for (const std::uint32_t index : t) normals[index] += n;
  }
  for (Eigen::Vector3d& n : normals) {
    // stableNorm avoids the under/overflow of squaring tiny or huge components.
    const double length = n.stableNorm();
    if (length > 0.0 && std::isfinite(length)) {
      n /= length;
    } else {
      n.setZero();
    }
  }
}

}  // namespace deformable_flsm
