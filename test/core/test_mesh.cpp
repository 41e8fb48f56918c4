/// @file test_mesh.cpp
/// Tests of core/mesh.h: loading every supported format, welding, validation, boundary edges and
/// vertex normals. Mesh files are written into a fresh temporary directory per test.
#include "deformable_flsm/core/mesh.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace {

using test::signedVolume;

namespace fs = std::filesystem;

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;

/// Corners of the unit cube [0, 1]^3; corner v has coordinates (v & 1, (v >> 1) & 1, v >> 2).
std::vector<Eigen::Vector3d> cubeCorners() {
  std::vector<Eigen::Vector3d> corners;
  for (int v = 0; v < 8; ++v) corners.emplace_back(v & 1, (v >> 1) & 1, v >> 2);
  return corners;
}

/// The six faces of the unit cube as quads, counter-clockwise seen from outside, each starting
/// at its corner of even parity (x + y + z even) so that splitting a quad (a, b, c, d) into
/// (a, b, c) and (a, c, d) always cuts along the diagonal joining the two even corners.
const std::vector<std::array<std::uint32_t, 4>> kCubeQuads = {
    {0, 2, 3, 1},  // z = 0
    {5, 7, 6, 4},  // z = 1
    {0, 1, 5, 4},  // y = 0
    {6, 7, 3, 2},  // y = 1
    {0, 4, 6, 2},  // x = 0
    {3, 7, 5, 1},  // x = 1
};

/// The unit cube as 12 counter-clockwise triangles (two per face, split as described above).
TriMesh unitCube() {
  TriMesh mesh;
  mesh.vertices = cubeCorners();
  for (const auto& q : kCubeQuads) {
    mesh.triangles.push_back({q[0], q[1], q[2]});
    mesh.triangles.push_back({q[0], q[2], q[3]});
  }
  return mesh;
}


/// A fresh directory under the system temp dir, removed after each test.
class MeshFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device random;
    dir_ = fs::temp_directory_path() /
           ("deformable_flsm_test_mesh_" + std::to_string(random()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  /// Writes `contents` to a file named `name` in the test directory and returns its path.
  std::string write(const std::string& name, const std::string& contents) const {
    const fs::path path = dir_ / name;
    std::ofstream out(path, std::ios::binary);
    out << contents;
    return path.string();
  }

  fs::path dir_;
};

std::string cubeObj() {
  std::string s = "# unit cube, quads\n";
  for (const auto& c : cubeCorners()) {
    s += "v " + std::to_string(c.x()) + " " + std::to_string(c.y()) + " " +
         std::to_string(c.z()) + "\n";
  }
  for (const auto& q : kCubeQuads) {
    s += "f " + std::to_string(q[0] + 1) + " " + std::to_string(q[1] + 1) + " " +
         std::to_string(q[2] + 1) + " " + std::to_string(q[3] + 1) + "\n";
  }
  return s;
}

/// The cube's vertex lines ("x y z") and quad lines ("4 a b c d"), as OFF and ASCII PLY both
/// write them after their headers.
std::string cubeVertexAndFaceLines() {
  std::string s;
  for (const auto& c : cubeCorners()) {
    s += std::to_string(c.x()) + " " + std::to_string(c.y()) + " " + std::to_string(c.z()) + "\n";
  }
  for (const auto& q : kCubeQuads) {
    s += "4 " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) +
         " " + std::to_string(q[3]) + "\n";
  }
  return s;
}

std::string cubeOff() { return "OFF\n8 6 0\n" + cubeVertexAndFaceLines(); }

std::string cubePly() {
  std::string s =
      "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
      "property float z\nelement face 6\nproperty list uchar int vertex_indices\nend_header\n";
  return s + cubeVertexAndFaceLines();
}

/// STL stores each facet's three corners separately, so this is a 36-corner triangle soup.
std::string cubeStlAscii() {
  const TriMesh cube = unitCube();
  std::string s = "solid cube\n";
  for (const auto& t : cube.triangles) {
    s += " facet normal 0 0 0\n  outer loop\n";
    for (const std::uint32_t v : t) {
      const Eigen::Vector3d& p = cube.vertices[v];
      s += "   vertex " + std::to_string(p.x()) + " " + std::to_string(p.y()) + " " +
           std::to_string(p.z()) + "\n";
    }
    s += "  endloop\n endfacet\n";
  }
  return s + "endsolid cube\n";
}

std::string cubeStlBinary() {
  const TriMesh cube = unitCube();
  std::string s(80, ' ');
  s.replace(0, 11, "binary cube");  // must not start with "solid", the ASCII keyword
  auto append = [&s](const void* data, std::size_t size) {
    s.append(static_cast<const char*>(data), size);
  };
  const std::uint32_t count = static_cast<std::uint32_t>(cube.triangles.size());
  append(&count, sizeof count);
  for (const auto& t : cube.triangles) {
    const float normal[3] = {0.0f, 0.0f, 0.0f};
    append(normal, sizeof normal);
    for (const std::uint32_t v : t) {
      const float p[3] = {static_cast<float>(cube.vertices[v].x()),
                          static_cast<float>(cube.vertices[v].y()),
                          static_cast<float>(cube.vertices[v].z())};
      append(p, sizeof p);
    }
    const std::uint16_t attributes = 0;
    append(&attributes, sizeof attributes);
  }
  return s;
}

/// Two instances of the unit cube: one at the root, one under a translated node whose child
/// scales by 2, so the second lands on [3, 5] x [0, 2] x [0, 2].
std::string twoCubesDae() {
  std::string positions;
  for (const auto& c : cubeCorners()) {
    positions += std::to_string(c.x()) + " " + std::to_string(c.y()) + " " +
                 std::to_string(c.z()) + " ";
  }
  std::string indices;
  for (const auto& t : unitCube().triangles) {
    for (const std::uint32_t v : t) indices += std::to_string(v) + " ";
  }
  return R"(<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries>
    <geometry id="cube" name="cube">
      <mesh>
        <source id="cube-pos">
          <float_array id="cube-pos-array" count="24">)" +
         positions + R"(</float_array>
          <technique_common>
            <accessor source="#cube-pos-array" count="8" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/>
              <param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="cube-vtx"><input semantic="POSITION" source="#cube-pos"/></vertices>
        <triangles count="12">
          <input semantic="VERTEX" source="#cube-vtx" offset="0"/>
          <p>)" +
         indices + R"(</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="a"><instance_geometry url="#cube"/></node>
      <node id="b">
        <translate>3 0 0</translate>
        <node id="c"><scale>2 2 2</scale><instance_geometry url="#cube"/></node>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
)";
}

/// Expects `call` to throw MeshError whose message contains every one of `phrases`.
template <typename Call>
void expectMeshError(Call call, const std::vector<std::string>& phrases) {
  try {
    call();
    ADD_FAILURE() << "expected MeshError";
  } catch (const MeshError& error) {
    const std::string message = error.what();
    for (const std::string& phrase : phrases) {
      EXPECT_NE(message.find(phrase), std::string::npos)
          << "message \"" << message << "\" lacks \"" << phrase << "\"";
    }
  }
}

TEST(UnitCubeFixture, IsClosedAndOutwardOriented) {
  // Guards the fixture itself: every other test relies on it being a correct cube.
  const TriMesh cube = unitCube();
  EXPECT_EQ(countBoundaryEdges(cube), 0u);
  EXPECT_DOUBLE_EQ(signedVolume(cube), 1.0);
}

TEST_F(MeshFileTest, EveryFormatLoadsTheCubeAsEightVerticesAndTwelveTriangles) {
  const std::vector<std::pair<std::string, std::string>> files = {
      {"cube.obj", cubeObj()},          {"cube.off", cubeOff()},
      {"cube.ply", cubePly()},          {"cube_ascii.stl", cubeStlAscii()},
      {"cube_binary.stl", cubeStlBinary()},
  };
  for (const auto& [name, contents] : files) {
    SCOPED_TRACE(name);
    const TriMesh mesh = loadMesh(write(name, contents));
    // STL's 36 separate corners must be welded back to the 8 corners.
    EXPECT_EQ(mesh.vertices.size(), 8u);
    EXPECT_EQ(mesh.triangles.size(), 12u);
    EXPECT_EQ(countBoundaryEdges(mesh), 0u);
    // Coordinates 0 and 1 are exact in every format (text and float32), so are the bounds.
    EXPECT_EQ(mesh.boundsMin(), Eigen::Vector3d::Zero());
    EXPECT_EQ(mesh.boundsMax(), Eigen::Vector3d::Ones());
    // Orientation survives loading: volume +1, exact in floating point for these coordinates
    // (each term is a small integer over 6); 1e-12 leaves room for summation order only.
    EXPECT_NEAR(signedVolume(mesh), 1.0, 1e-12);
  }
}

TEST_F(MeshFileTest, ScaleMultipliesEveryCoordinate) {
  const TriMesh mesh = loadMesh(write("cube.obj", cubeObj()), 2.5);
  EXPECT_EQ(mesh.boundsMin(), Eigen::Vector3d::Zero());
  EXPECT_EQ(mesh.boundsMax(), Eigen::Vector3d::Constant(2.5));  // 1 * 2.5 is exact
  EXPECT_NEAR(signedVolume(mesh), 2.5 * 2.5 * 2.5, 1e-12);
}

TEST_F(MeshFileTest, ColladaNodeTransformsAreAppliedAndMeshesMerged) {
  const TriMesh mesh = loadMesh(write("two_cubes.dae", twoCubesDae()));
  EXPECT_EQ(mesh.vertices.size(), 16u);
  EXPECT_EQ(mesh.triangles.size(), 24u);
  EXPECT_EQ(countBoundaryEdges(mesh), 0u);
  // Node transforms are composed in single precision by assimp; 1e-6 covers float rounding of
  // values of order 5.
  EXPECT_LT(mesh.boundsMin().norm(), 1e-6) << mesh.boundsMin().transpose();
  EXPECT_TRUE(mesh.boundsMax().isApprox(Eigen::Vector3d(5.0, 2.0, 2.0), 1e-6))
      << mesh.boundsMax().transpose();
  // Volume 1 + 8: the scale of the child node reached the vertices.
  EXPECT_NEAR(signedVolume(mesh), 9.0, 1e-5);
}

TEST(LoadMesh, StanfordBunnyFromGlmark2IsClosed) {
  ASSERT_TRUE(fs::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const TriMesh bunny = loadMesh(kBunnyPath);
  // The file has 34,835 distinct positions and 69,666 triangles; welding finds no duplicates and
  // no degenerate triangles, so both counts are those of the file.
  EXPECT_EQ(bunny.vertices.size(), 34835u);
  EXPECT_EQ(bunny.triangles.size(), 69666u);
  // Closed (every edge shared by two triangles), and indeed T = 2 V - 4: a closed genus-0 surface.
  EXPECT_EQ(countBoundaryEdges(bunny), 0u);
  EXPECT_EQ(bunny.triangles.size(), 2 * bunny.vertices.size() - 4);
  EXPECT_GT(signedVolume(bunny), 0.0) << "triangles should face outwards";
  // About 2 units wide along x.
  EXPECT_NEAR((bunny.boundsMax() - bunny.boundsMin()).x(), 2.0, 1e-6);
}

TEST_F(MeshFileTest, Glmark2JobjIsReadFromItsIndexLines) {
  // glmark2's own format: vertex lines (with normals, texture coordinates and colours beside
  // them) and one index per line, three per triangle.
  std::string jobj;
  for (const auto& c : cubeCorners()) {
    jobj += "v " + std::to_string(c.x()) + " " + std::to_string(c.y()) + " " +
            std::to_string(c.z()) + "\nvn 0 0 1\nvt 0 0\nvc 1 1 1 1\n";
  }
  for (const auto& q : kCubeQuads)
    for (int k : {0, 1, 2, 0, 2, 3}) jobj += "i " + std::to_string(q[k]) + "\n";
  const TriMesh cube = loadMesh(write("cube.jobj", jobj), 2.0);
  EXPECT_EQ(cube.vertices.size(), 8u);
  EXPECT_EQ(cube.triangles.size(), 12u);
  EXPECT_EQ(countBoundaryEdges(cube), 0u);
  EXPECT_NEAR(std::abs(signedVolume(cube)), 8.0, 1e-9);  // the unit cube scaled by 2

  expectMeshError([&] { loadMesh(write("short.jobj", "v 0 0 0\nv 1 0 0\ni 0\ni 1\n")); },
                  {"short.jobj", "2 indices"});
}

TEST(LoadMesh, Glmark2JellyfishLoads) {
  const std::string path = std::string(deformable_flsm::kGlmark2ModelDirectory) + "/jellyfish.jobj";
  ASSERT_TRUE(fs::exists(path)) << path << " missing: install glmark2-data (a test dependency)";
  const TriMesh jellyfish = loadMesh(path);
  EXPECT_GT(jellyfish.triangles.size(), 1000u);  // 13,200 index lines: 4400 triangles
  EXPECT_LE(jellyfish.triangles.size(), 4400u);
}

TEST_F(MeshFileTest, MissingFileIsNamed) {
  const std::string path = (dir_ / "no_such_mesh.obj").string();
  expectMeshError([&] { loadMesh(path); }, {path, "does not exist"});
}

TEST_F(MeshFileTest, UnsupportedFormatCarriesAssimpReason) {
  const std::string path = write("notes.xyz", "hello world\n");
  expectMeshError([&] { loadMesh(path); }, {path, "cannot read", "No suitable reader"});
}

TEST_F(MeshFileTest, CorruptFileIsUnreadable) {
  const std::string path = write("broken.obj", "hello\n");
  expectMeshError([&] { loadMesh(path); }, {path, "cannot read"});
}

TEST_F(MeshFileTest, LinesOnlyHaveNoTriangles) {
  const std::string path = write("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n");
  expectMeshError([&] { loadMesh(path); }, {path, "no triangles"});
}

TEST_F(MeshFileTest, NonFiniteCoordinatesAreRejected) {
  const std::string path = write("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expectMeshError([&] { loadMesh(path); }, {path, "non-finite"});
}

TEST_F(MeshFileTest, ScaleThatOverflowsIsNonFinite) {
  // Finite in the file, 1e10 * 1e300 overflows to infinity once scaled.
  const std::string path = write("big.obj", "v 0 0 0\nv 1e10 0 0\nv 0 1 0\nf 1 2 3\n");
  expectMeshError([&] { loadMesh(path, 1e300); }, {path, "non-finite"});
}

TEST_F(MeshFileTest, PointLikeMeshHasZeroExtent) {
  const std::string path = write("point.obj", "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n");
  expectMeshError([&] { loadMesh(path); }, {path, "zero extent"});
}

TEST_F(MeshFileTest, NonPositiveOrNonFiniteScaleIsRejected) {
  const std::string path = write("cube.obj", cubeObj());
  for (const double scale : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity()}) {
    SCOPED_TRACE(scale);
    expectMeshError([&] { loadMesh(path, scale); }, {path, "scale"});
  }
}

TEST(ValidateMesh, AcceptsTheCube) { EXPECT_NO_THROW(validateMesh(unitCube(), "cube")); }

TEST(ValidateMesh, NamesEachProblem) {
  expectMeshError([] { validateMesh(TriMesh{}, "empty"); }, {"'empty'", "no triangles"});

  TriMesh outOfRange = unitCube();
  outOfRange.triangles[3][1] = 8;
  expectMeshError([&] { validateMesh(outOfRange, "oor"); }, {"'oor'", "triangle 3", "vertex 8"});

  TriMesh infinite = unitCube();
  infinite.vertices[5].y() = std::numeric_limits<double>::infinity();
  expectMeshError([&] { validateMesh(infinite, "inf"); }, {"'inf'", "non-finite", "vertex 5"});

  TriMesh point = unitCube();
  for (Eigen::Vector3d& v : point.vertices) v = Eigen::Vector3d(0.5, 0.5, 0.5);
  expectMeshError([&] { validateMesh(point, "pt"); }, {"'pt'", "zero extent"});
}

TEST(WeldVertices, JoinsTriangleSoupBackIntoTheCube) {
  const TriMesh cube = unitCube();
  TriMesh soup;
  for (const auto& t : cube.triangles) {
    const auto base = static_cast<std::uint32_t>(soup.vertices.size());
    for (const std::uint32_t v : t) soup.vertices.push_back(cube.vertices[v]);
    soup.triangles.push_back({base, base + 1, base + 2});
  }
  EXPECT_EQ(countBoundaryEdges(soup), 36u);  // every edge of the soup is used once
  EXPECT_EQ(weldVertices(soup), 28u);        // 36 corners -> 8 positions
  EXPECT_EQ(soup.vertices.size(), 8u);
  EXPECT_EQ(soup.triangles.size(), 12u);
  EXPECT_EQ(countBoundaryEdges(soup), 0u);
  EXPECT_DOUBLE_EQ(signedVolume(soup), 1.0);
}

TEST(WeldVertices, DropsTrianglesThatBecomeDegenerateAndTreatsZerosAlike) {
  TriMesh mesh;
  mesh.vertices = {{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {-0.0, 0.0, -0.0},
                   {1.0, 0.0, 1e-300}};
  mesh.triangles = {{0, 1, 2}, {3, 1, 2}, {0, 3, 1}};
  // -0.0 == 0.0, so vertex 3 joins vertex 0 and triangle (0, 3, 1) collapses; vertex 4 differs
  // from vertex 1 by 1e-300, which is not equal, so it stays.
  EXPECT_EQ(weldVertices(mesh), 1u);
  EXPECT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(mesh.triangles[1], (std::array<std::uint32_t, 3>{0, 1, 2}));
}

TEST(CountBoundaryEdges, CountsEdgesNotSharedByExactlyTwoTriangles) {
  TriMesh open = unitCube();
  open.triangles.resize(10);  // drop the two triangles of the x = 1 face: its 4 sides are open
  EXPECT_EQ(countBoundaryEdges(open), 4u);

  TriMesh single;
  single.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  single.triangles = {{0, 1, 2}};
  EXPECT_EQ(countBoundaryEdges(single), 3u);

  // Three triangles on one edge (non-manifold): that edge counts, as do the six outer edges.
  TriMesh fan;
  fan.vertices = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}};
  fan.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  EXPECT_EQ(countBoundaryEdges(fan), 7u);
}

TEST(ComputeVertexNormals, CubeCornersPointAlongTheDiagonals) {
  // With the fixture's split, each corner has the same area (1 or 1/2) on each of its three
  // faces, so the area-weighted normal is exactly along (+-1, +-1, +-1). The only error is the
  // rounding of the normalisation, a few ulps, hence 1e-12.
  const TriMesh cube = unitCube();
  std::vector<Eigen::Vector3d> normals;
  computeVertexNormals(cube.vertices, cube.triangles, normals);
  ASSERT_EQ(normals.size(), 8u);
  for (std::size_t v = 0; v < 8; ++v) {
    const Eigen::Vector3d expected =
        (2.0 * cube.vertices[v] - Eigen::Vector3d::Ones()).normalized();
    EXPECT_LT((normals[v] - expected).norm(), 1e-12) << "corner " << v;
  }
}

TEST(ComputeVertexNormals, WeightsFacesByArea) {
  // Vertex 0 is shared by a triangle of area 2 facing +z and one of area 1/2 facing +y, so its
  // normal is (0, 1/2, 2) normalised.
  const std::vector<Eigen::Vector3d> positions = {
      {0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, {1, 0, 0}};
  const std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}, {0, 3, 4}};
  std::vector<Eigen::Vector3d> normals;
  computeVertexNormals(positions, triangles, normals);
  EXPECT_LT((normals[0] - Eigen::Vector3d(0.0, 0.5, 2.0).normalized()).norm(), 1e-12);
  EXPECT_LT((normals[1] - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_LT((normals[3] - Eigen::Vector3d::UnitY()).norm(), 1e-12);
}

TEST(ComputeVertexNormals, DegenerateTrianglesAndIsolatedVerticesGiveZeroNotNaN) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Eigen::Vector3d> positions = {
      {0, 0, 0}, {1, 1, 1}, {2, 2, 2},  // collinear: zero area
      {5, 5, 5},                        // used by no triangle
      {3, 3, 3},                        // all three corners of a triangle at one point
      {nan, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<std::array<std::uint32_t, 3>> triangles = {
      {0, 1, 2}, {4, 4, 4}, {5, 6, 7}};
  std::vector<Eigen::Vector3d> normals;
  computeVertexNormals(positions, triangles, normals);
  ASSERT_EQ(normals.size(), positions.size());
  for (const Eigen::Vector3d& n : normals) {
    EXPECT_TRUE(n.allFinite());
    EXPECT_EQ(n, Eigen::Vector3d::Zero());
  }
}

TEST(ComputeVertexNormals, OverflowingCrossProductGivesZeroNotNaN) {
  // Edges of 1e200 have a cross product of 1e400, which overflows; such a face is skipped.
  const std::vector<Eigen::Vector3d> positions = {{0, 0, 0}, {1e200, 0, 0}, {0, 1e200, 0}};
  std::vector<Eigen::Vector3d> normals;
  computeVertexNormals(positions, {{0, 1, 2}}, normals);
  for (const Eigen::Vector3d& n : normals) EXPECT_EQ(n, Eigen::Vector3d::Zero());
}

TEST(ComputeVertexNormals, RejectsOutOfRangeIndices) {
  std::vector<Eigen::Vector3d> normals;
  EXPECT_THROW(computeVertexNormals({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 1, 3}}, normals),
               MeshError);
}

}  // namespace
}  // namespace deformable_flsm
