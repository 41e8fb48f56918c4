/// @file test_voxelizer.cpp
/// Tests of core/voxelizer.h: options, lattice placement, exact counts on a cube, volume of a
/// sphere, parity robustness on rays through edges and vertices, open meshes, the particle budget,
/// the triangle/box overlap test and the Stanford bunny.
#include "deformable_flsm/core/voxelizer.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <tuple>
#include <vector>

namespace deformable_flsm {
namespace {

using test::signedVolume;

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;


TriMesh unitCube() { return test::boxMesh(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()); }

/// Icosahedron subdivided `levels` times, vertices projected onto the sphere of `radius` at the
/// origin; counter-clockwise seen from outside.
TriMesh icosphere(int levels, double radius) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriMesh mesh;
  mesh.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                   {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoints;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      const auto found = midpoints.find(key);
      if (found != midpoints.end()) return found->second;
      const auto index = static_cast<std::uint32_t>(mesh.vertices.size());
      mesh.vertices.push_back((mesh.vertices[a] + mesh.vertices[b]) / 2.0);
      midpoints.emplace(key, index);
      return index;
    };
    std::vector<std::array<std::uint32_t, 3>> finer;
    for (const auto& f : mesh.triangles) {
      const std::uint32_t ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]),
                          ca = midpoint(f[2], f[0]);
      finer.push_back({f[0], ab, ca});
      finer.push_back({f[1], bc, ab});
      finer.push_back({f[2], ca, bc});
      finer.push_back({ab, bc, ca});
    }
    mesh.triangles = std::move(finer);
  }
  for (Eigen::Vector3d& v : mesh.vertices) v = radius * v.normalized();
  return mesh;
}


double filledVolume(const Voxelization& v) {
  double sum = 0.0;
  for (const double f : v.fillFraction) sum += f;
  return sum * v.spacing * v.spacing * v.spacing;
}

VoxelizeOptions withResolution(int resolution, std::size_t maxParticles = 200000) {
  VoxelizeOptions options;
  options.resolution = resolution;
  options.maxParticles = maxParticles;
  return options;
}

/// Number of 6-connected components of the listed cells.
int countComponents(const std::vector<Eigen::Vector3i>& cells) {
  std::set<std::tuple<int, int, int>> unvisited;
  for (const Eigen::Vector3i& c : cells) unvisited.emplace(c.x(), c.y(), c.z());
  int components = 0;
  while (!unvisited.empty()) {
    ++components;
    std::vector<std::tuple<int, int, int>> stack = {*unvisited.begin()};
    unvisited.erase(unvisited.begin());
    while (!stack.empty()) {
      const auto [i, j, k] = stack.back();
      stack.pop_back();
      const std::tuple<int, int, int> neighbours[6] = {{i + 1, j, k}, {i - 1, j, k},
                                                       {i, j + 1, k}, {i, j - 1, k},
                                                       {i, j, k + 1}, {i, j, k - 1}};
      for (const auto& n : neighbours) {
        const auto found = unvisited.find(n);
        if (found == unvisited.end()) continue;
        stack.push_back(n);
        unvisited.erase(found);
      }
    }
  }
  return components;
}

/// Invariants every voxelization must satisfy: cells inside dims, strictly increasing in
/// (k, j, i) (hence sorted and unique), one fraction per cell, each in (0, 1].
void expectWellFormed(const Voxelization& v) {
  ASSERT_EQ(v.cells.size(), v.fillFraction.size());
  for (std::size_t p = 0; p < v.cells.size(); ++p) {
    const Eigen::Vector3i& c = v.cells[p];
    ASSERT_TRUE((c.array() >= 0).all() && (c.array() < v.dims.array()).all()) << c.transpose();
    ASSERT_GT(v.fillFraction[p], 0.0);
    ASSERT_LE(v.fillFraction[p], 1.0);
    if (p > 0) {
      const Eigen::Vector3i& b = v.cells[p - 1];
      ASSERT_LT(std::make_tuple(b.z(), b.y(), b.x()), std::make_tuple(c.z(), c.y(), c.x()));
    }
  }
}

/// The resolution named after "use resolution " in a budget error message, or -1.
int suggestedResolution(const std::string& message) {
  std::smatch match;
  if (!std::regex_search(message, match, std::regex("use resolution ([0-9]+)"))) return -1;
  return std::stoi(match[1]);
}

TEST(VoxelizeOptions, AcceptsExactlyOneOfSpacingAndResolution) {
  VoxelizeOptions byResolution;
  byResolution.resolution = 10;
  EXPECT_NO_THROW(byResolution.validate());
  VoxelizeOptions bySpacing;
  bySpacing.spacing = 0.1;
  EXPECT_NO_THROW(bySpacing.validate());
}

TEST(VoxelizeOptions, NamesTheOffendingField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Case {
    double spacing;
    int resolution;
    std::size_t maxParticles;
    const char* field;
  };
  const Case cases[] = {
      {0.0, 0, 100, "spacing and VoxelizeOptions::resolution"},  // neither
      {0.1, 10, 100, "spacing and VoxelizeOptions::resolution"},  // both
      {nan, 10, 100, "VoxelizeOptions::spacing"},
      {inf, 0, 100, "VoxelizeOptions::spacing"},
      {-0.1, 0, 100, "VoxelizeOptions::spacing"},
      {0.0, -4, 100, "VoxelizeOptions::resolution"},
      {0.0, 10, 0, "VoxelizeOptions::maxParticles"},
  };
  for (const Case& c : cases) {
    VoxelizeOptions options;
    options.spacing = c.spacing;
    options.resolution = c.resolution;
    options.maxParticles = c.maxParticles;
    SCOPED_TRACE(c.field);
    try {
      options.validate();
      ADD_FAILURE() << "expected VoxelizationError";
    } catch (const VoxelizationError& error) {
      EXPECT_NE(std::string(error.what()).find(c.field), std::string::npos) << error.what();
    }
    // voxelize() checks its options before touching the mesh.
    EXPECT_THROW(voxelize(unitCube(), options), VoxelizationError);
  }
}

TEST(Voxelize, RejectsAnInvalidMesh) {
  EXPECT_THROW(voxelize(TriMesh{}, withResolution(4)), MeshError);
}

TEST(Voxelize, CubeGivesExactlyNCubedFullCells) {
  // The cube's faces fall on cell boundaries; cells outside merely touch a face (no volume) and
  // must not be occupied, cells inside are full. Sub-samples sit h/8 from any face, so the
  // counts are exact, not approximate.
  for (const int n : {1, 2, 5, 8}) {
    SCOPED_TRACE(n);
    const Voxelization v = voxelize(unitCube(), withResolution(n));
    expectWellFormed(v);
    EXPECT_TRUE(v.closed);
    EXPECT_TRUE(v.warnings.empty());
    EXPECT_EQ(v.dims, Eigen::Vector3i::Constant(n));
    EXPECT_DOUBLE_EQ(v.spacing, 1.0 / n);
    EXPECT_LT(v.origin.norm(), 1e-15);  // dims * h - extent is 0 up to rounding
    ASSERT_EQ(v.cells.size(), static_cast<std::size_t>(n * n * n));
    for (const double f : v.fillFraction) EXPECT_EQ(f, 1.0);
  }
}

// By spacing too: a box of n cells per side gives n^3 cells, also when size / spacing is not
// exactly n in floating point (0.1 / 0.025 is 4 + 1 ulp, 0.7 / 0.1 is 7 - 1 ulp; a mesh file's
// single-precision 0.1f is 4 + 6e-8 cells of 0.025) and when the box does not start at the origin.
TEST(Voxelize, BoxOfWholeCellsBySpacingGivesExactlyTheCells) {
  struct Case {
    Eigen::Vector3d lo, size;
    double spacing;
  };
  for (const Case& c : {Case{Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(0.1), 0.025},
                        Case{Eigen::Vector3d(0.3, -0.2, 0.7), Eigen::Vector3d::Constant(0.1), 0.025},
                        Case{Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0.3, 0.7), 0.1},
                        Case{Eigen::Vector3d(-0.35, 0.1, 0.05), Eigen::Vector3d(0.7, 0.3, 0.15), 0.05},
                        Case{Eigen::Vector3d::Zero(), Eigen::Vector3d(1.0, 0.1, 0.1), 0.0125},
                        // a mesh file in single precision: 0.1f is 0.1 + 1.5e-9, 4 + 6e-8 cells
                        Case{Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(double(0.1f)), 0.025},
                        Case{Eigen::Vector3d::Constant(double(-0.05f)), Eigen::Vector3d::Constant(double(0.05f) - double(-0.05f)), 0.025}}) {
    const Eigen::Vector3i n = (c.size / c.spacing).array().round().cast<int>();
    SCOPED_TRACE(testing::Message() << "box " << c.size.transpose() << " at spacing " << c.spacing);
    VoxelizeOptions o;
    o.spacing = c.spacing;
    const Voxelization v = voxelize(test::boxMesh(c.lo, c.lo + c.size), o);
    EXPECT_EQ(v.dims, n);
    EXPECT_EQ(v.cells.size(), static_cast<std::size_t>(n.prod()));
    for (const double f : v.fillFraction) EXPECT_NEAR(f, 1.0, 1e-12);
  }
}

TEST(Voxelize, LatticeIsCentredOnTheBoundingBox) {
  // Extents 1 x 0.75 x 0.3 at h = 0.25: 4 x 3 x 2 cells (0.3 / 0.25 = 1.2 rounds up), and the
  // 0.2 of slack along z is split evenly below and above the box.
  const Eigen::Vector3d lo(-2.0, 3.0, 0.5);
  const Eigen::Vector3d hi = lo + Eigen::Vector3d(1.0, 0.75, 0.3);
  const Voxelization v = voxelize(test::boxMesh(lo, hi), withResolution(4));
  expectWellFormed(v);
  EXPECT_EQ(v.dims, Eigen::Vector3i(4, 3, 2));
  EXPECT_DOUBLE_EQ(v.spacing, 0.25);
  // 1e-12: the few roundings of origin = lo - (dims h - extent) / 2 at coordinates of order 1.
  EXPECT_LT((v.origin - (lo - Eigen::Vector3d(0.0, 0.0, 0.1))).norm(), 1e-12);
  // Every cell is cut by the box in z only: half of each cell's z sub-samples lie inside
  // (cell 0 covers z in [-0.1, 0.15] of the box's [0, 0.3], samples at -0.069, -0.006, 0.056,
  // 0.119; cell 1 covers [0.15, 0.4], samples at 0.181, 0.244, 0.306, 0.369).
  ASSERT_EQ(v.cells.size(), 24u);
  for (const double f : v.fillFraction) EXPECT_EQ(f, 0.5);
  // A long mesh: the resolution counts cells along the longest axis.
  const Voxelization rod = voxelize(test::boxMesh(Eigen::Vector3d::Zero(), {10.0, 1.0, 0.5}),
                                    withResolution(10));
  EXPECT_EQ(rod.dims, Eigen::Vector3i(10, 1, 1));
  EXPECT_EQ(rod.cells.size(), 10u);
}

TEST(Voxelize, SphereVolumeAndConnectivity) {
  // 4 subdivisions: 5,120 triangles. The reference is the mesh's own volume, so faceting error
  // does not enter the comparison.
  const double radius = 1.0;
  const TriMesh sphere = icosphere(4, radius);
  ASSERT_EQ(countBoundaryEdges(sphere), 0u);
  const double exact = signedVolume(sphere);
  const Voxelization v = voxelize(sphere, withResolution(32));
  expectWellFormed(v);
  EXPECT_TRUE(v.closed);
  EXPECT_TRUE(v.warnings.empty());
  const double error = (filledVolume(v) - exact) / exact;
  std::cout << "[ sphere   ] resolution 32: " << v.cells.size() << " cells, filled volume "
            << filledVolume(v) << " vs mesh volume " << exact << ", relative error " << error
            << "\n";
  // Each surface cell's fraction is a 64-sample estimate (error up to 1/64 of a cell, of either
  // sign); over ~3,000 surface cells the errors largely cancel, to about 0.1% here. 5% is the
  // contract's bound; 1% is what a regression in the sampling would break first.
  EXPECT_LT(std::abs(error), 0.05);
  EXPECT_LT(std::abs(error), 0.01);
  EXPECT_EQ(countComponents(v.cells), 1);

  // Geometric invariants. The polyhedron contains the ball of its smallest face-plane distance
  // and lies in the circumscribed ball of `radius`. A cell whose box is inside the inner ball
  // must be full; a cell whose box is outside the outer ball must be absent.
  double inner = radius;
  for (const auto& t : sphere.triangles) {
    const Eigen::Vector3d& a = sphere.vertices[t[0]];
    const Eigen::Vector3d n =
        (sphere.vertices[t[1]] - a).cross(sphere.vertices[t[2]] - a).normalized();
    inner = std::min(inner, n.dot(a));
  }
  const double halfDiagonal = std::sqrt(3.0) / 2.0 * v.spacing;
  std::set<std::tuple<int, int, int>> listed;
  for (std::size_t p = 0; p < v.cells.size(); ++p) {
    const Eigen::Vector3i& c = v.cells[p];
    listed.emplace(c.x(), c.y(), c.z());
    const double d = v.cellCenter(c).norm();
    EXPECT_LE(d - halfDiagonal, radius) << "cell outside the sphere: " << c.transpose();
    if (d + halfDiagonal < inner) {
      EXPECT_EQ(v.fillFraction[p], 1.0) << c.transpose();
    }
  }
  for (int k = 0; k < v.dims.z(); ++k) {
    for (int j = 0; j < v.dims.y(); ++j) {
      for (int i = 0; i < v.dims.x(); ++i) {
        if (v.cellCenter({i, j, k}).norm() + halfDiagonal < inner) {
          EXPECT_TRUE(listed.count({i, j, k})) << "interior cell missing: " << i << " " << j
                                               << " " << k;
        }
      }
    }
  }
}

TEST(Voxelize, ParityIsRobustForRaysThroughEdgesAndVertices) {
  // At resolution 1 the sample rays of the unit cube's single cell run at y, z in
  // {1/8, 3/8, 5/8, 7/8}. Triangulate the x = 0 and x = 1 faces as fans around (x, 3/8, 3/8):
  // the ray (3/8, 3/8) passes exactly through both fan centres, and rays (1/8, 1/8), (5/8, 5/8),
  // (7/8, 7/8) exactly along the fan edges to the corners (0, 0) and (1, 1). Each ray must still
  // cross each face exactly once, so all 64 samples are inside.
  TriMesh mesh = unitCube();
  mesh.triangles.erase(mesh.triangles.begin(), mesh.triangles.begin() + 4);  // x faces
  for (const double x : {0.0, 1.0}) {
    const auto centre = static_cast<std::uint32_t>(mesh.vertices.size());
    mesh.vertices.emplace_back(x, 0.375, 0.375);
    // Corners of the face in counter-clockwise order seen from +x.
    const int base = x == 0.0 ? 0 : 1;
    std::uint32_t ring[4] = {std::uint32_t(base), std::uint32_t(base + 2),
                             std::uint32_t(base + 6), std::uint32_t(base + 4)};
    if (x == 0.0) std::swap(ring[1], ring[3]);  // seen from outside (-x) the order reverses
    for (int e = 0; e < 4; ++e) mesh.triangles.push_back({centre, ring[e], ring[(e + 1) % 4]});
  }
  ASSERT_EQ(countBoundaryEdges(mesh), 0u);
  ASSERT_DOUBLE_EQ(signedVolume(mesh), 1.0);
  const Voxelization v = voxelize(mesh, withResolution(1));
  EXPECT_TRUE(v.warnings.empty()) << v.warnings.front();
  ASSERT_EQ(v.cells.size(), 1u);
  EXPECT_EQ(v.fillFraction[0], 1.0);
}

TEST(Voxelize, ParityIsRobustForRaysGrazingSilhouetteEdges) {
  // Octahedron |x - 1/2| + |y - 1/2| + |z - 1/2| <= 1/2. Seen along x its silhouette is the
  // square |y - 1/2| + |z - 1/2| = 1/2, on which the rays (1/8, 3/8), (3/8, 1/8), ... lie
  // exactly: they touch the surface at one point without entering. Of the 64 samples (offsets
  // +-1/8, +-3/8 from the centre) exactly the 8 with all offsets +-1/8 are inside (sum 3/8 <
  // 1/2; the next sum is 5/8), none on the surface: the fraction must be exactly 8/64.
  TriMesh mesh;
  mesh.vertices = {{0, .5, .5}, {1, .5, .5}, {.5, 0, .5}, {.5, 1, .5}, {.5, .5, 0}, {.5, .5, 1}};
  for (const std::uint32_t x : {0u, 1u}) {
    for (const std::uint32_t y : {2u, 3u}) {
      for (const std::uint32_t z : {4u, 5u}) {
        // Outward when the sign pattern of (x, y, z) has even parity, else flip.
        const bool flip = ((x == 1u) + (y == 3u) + (z == 5u)) % 2 == 0;
        mesh.triangles.push_back(flip ? std::array<std::uint32_t, 3>{x, z, y}
                                      : std::array<std::uint32_t, 3>{x, y, z});
      }
    }
  }
  ASSERT_EQ(countBoundaryEdges(mesh), 0u);
  ASSERT_NEAR(signedVolume(mesh), 1.0 / 6.0, 1e-15);
  const Voxelization v = voxelize(mesh, withResolution(1));
  EXPECT_TRUE(v.warnings.empty()) << v.warnings.front();
  ASSERT_EQ(v.cells.size(), 1u);
  EXPECT_EQ(v.fillFraction[0], 8.0 / 64.0);
}

TEST(Voxelize, CubeWithoutOneFaceIsOpenAndOnlyAShell) {
  TriMesh mesh = unitCube();
  mesh.triangles.erase(mesh.triangles.begin(), mesh.triangles.begin() + 2);  // x = 1 face
  const Voxelization v = voxelize(mesh, withResolution(4));
  expectWellFormed(v);
  EXPECT_FALSE(v.closed);
  ASSERT_EQ(v.warnings.size(), 2u);
  EXPECT_NE(v.warnings[0].find("mesh is open (4 boundary edges"), std::string::npos)
      << v.warnings[0];
  EXPECT_NE(v.warnings[1].find("only a shell"), std::string::npos) << v.warnings[1];
  // The flood fill enters through the missing face, so what remains are the cells touching the
  // five remaining faces: all 64 but the 3 x 2 x 2 with i >= 1 and j, k in {1, 2}.
  EXPECT_EQ(v.cells.size(), 64u - 12u);
  for (const double f : v.fillFraction) EXPECT_EQ(f, 1.0);
}

TEST(Voxelize, OpenMeshThatStillEnclosesIsFilled) {
  // A stray triangle inside the cube makes the mesh open (3 boundary edges) without letting the
  // flood fill in: every cell is occupied, at fraction 1, and only the "open" warning is given.
  TriMesh mesh = unitCube();
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), {{0.3, 0.3, 0.5}, {0.7, 0.3, 0.5}, {0.3, 0.7, 0.5}});
  mesh.triangles.push_back({base, base + 1, base + 2});
  const Voxelization v = voxelize(mesh, withResolution(5));
  EXPECT_FALSE(v.closed);
  ASSERT_EQ(v.warnings.size(), 1u);
  EXPECT_NE(v.warnings[0].find("mesh is open (3 boundary edges"), std::string::npos);
  EXPECT_EQ(v.cells.size(), 125u);
}

TEST(Voxelize, SpacingAndResolutionGiveTheSameLattice) {
  const TriMesh sphere = icosphere(3, 0.7);
  const double longest = (sphere.boundsMax() - sphere.boundsMin()).maxCoeff();
  const Voxelization byResolution = voxelize(sphere, withResolution(20));
  VoxelizeOptions options;
  options.spacing = longest / 20;
  const Voxelization bySpacing = voxelize(sphere, options);
  // Same h bit for bit, so everything downstream is identical, not merely close.
  EXPECT_EQ(byResolution.spacing, bySpacing.spacing);
  EXPECT_EQ(byResolution.origin, bySpacing.origin);
  EXPECT_EQ(byResolution.dims, bySpacing.dims);
  EXPECT_EQ(byResolution.cells, bySpacing.cells);
  EXPECT_EQ(byResolution.fillFraction, bySpacing.fillFraction);
}

/// Voxelizes with `options`, expecting the budget error; returns its message.
std::string budgetError(const TriMesh& mesh, const VoxelizeOptions& options) {
  try {
    voxelize(mesh, options);
  } catch (const VoxelizationError& error) {
    return error.what();
  }
  ADD_FAILURE() << "expected VoxelizationError";
  return {};
}

TEST(Voxelize, BudgetErrorNamesCountBudgetAndAResolutionThatFits) {
  // Cube at resolution 20: 8,000 cells against a budget of 1,000; resolution 10 fits exactly.
  const std::string cubeMessage = budgetError(unitCube(), withResolution(20, 1000));
  EXPECT_NE(cubeMessage.find("8000"), std::string::npos) << cubeMessage;
  EXPECT_NE(cubeMessage.find("maxParticles = 1000"), std::string::npos) << cubeMessage;
  EXPECT_EQ(suggestedResolution(cubeMessage), 10) << cubeMessage;

  // Sphere: the count does not scale exactly as resolution^3, so the suggestion is verified.
  const TriMesh sphere = icosphere(3, 1.0);
  for (const std::size_t budget : {std::size_t{1}, std::size_t{50}, std::size_t{3000}}) {
    SCOPED_TRACE(budget);
    const std::string message = budgetError(sphere, withResolution(40, budget));
    const int fit = suggestedResolution(message);
    ASSERT_GE(fit, 1) << message;
    EXPECT_LT(fit, 40);
    const Voxelization v = voxelize(sphere, withResolution(fit, budget));
    EXPECT_LE(v.cells.size(), budget);
  }
}

TEST(Voxelize, OversizedLatticeIsRefusedWithAResolutionThatFits) {
  // Spacing 1e-4 on a unit cube is a lattice of 10^12 cells, which must not be allocated.
  VoxelizeOptions options;
  options.spacing = 1e-4;
  const std::string message = budgetError(unitCube(), options);
  EXPECT_NE(message.find("lattice"), std::string::npos) << message;
  const int fit = suggestedResolution(message);
  ASSERT_GE(fit, 1) << message;
  EXPECT_LE(voxelize(unitCube(), withResolution(fit)).cells.size(), options.maxParticles);
}

TEST(TriangleBoxOverlap, SeparatingAxesOfEachKind) {
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  const Eigen::Vector3d e = Eigen::Vector3d::Ones();  // box [-1, 1]^3
  using detail::triangleBoxOverlap;
  // Inside, and enclosing the box in its plane.
  EXPECT_TRUE(triangleBoxOverlap(c, e, {0, 0, 0}, {.1, 0, 0}, {0, .1, 0}));
  EXPECT_TRUE(triangleBoxOverlap(c, e, {-10, -10, 0}, {10, -10, 0}, {0, 10, 0}));
  // Box normal: beside the box.
  EXPECT_FALSE(triangleBoxOverlap(c, e, {1.5, 0, 0}, {2, 1, 0}, {2, 0, 1}));
  // Touching counts: a triangle lying in the face x = 1, and one just beyond it.
  EXPECT_TRUE(triangleBoxOverlap(c, e, {1, 0, 0}, {1, 5, 0}, {1, 0, 5}));
  EXPECT_FALSE(triangleBoxOverlap(c, e, {1 + 1e-12, 0, 0}, {1 + 1e-12, 5, 0}, {1 + 1e-12, 0, 5}));
  // Triangle normal: the plane x + y + z = s cuts the corner (1, 1, 1) iff s < 3; the bounding
  // boxes overlap either way.
  EXPECT_TRUE(triangleBoxOverlap(c, e, {2.99, 0, 0}, {0, 2.99, 0}, {0, 0, 2.99}));
  EXPECT_FALSE(triangleBoxOverlap(c, e, {3.01, 0, 0}, {0, 3.01, 0}, {0, 0, 3.01}));
  // Edge cross product: in the plane z = 0 near the box's edge x = y = 1; the triangle's edge
  // x + y = s passes the corner of the square iff s < 2. Only the axis z x (edge) separates.
  EXPECT_TRUE(triangleBoxOverlap(c, e, {-0.1, 2, 0}, {2, -0.1, 0}, {2, 2, 0}));
  EXPECT_FALSE(triangleBoxOverlap(c, e, {0.1, 2, 0}, {2, 0.1, 0}, {2, 2, 0}));
  // Degenerate triangles: a segment through the box, and a point outside.
  EXPECT_TRUE(triangleBoxOverlap(c, e, {-3, -3, -3}, {3, 3, 3}, {0, 0, 0}));
  EXPECT_FALSE(triangleBoxOverlap(c, e, {2, 2, 2}, {2, 2, 2}, {2, 2, 2}));
}

TEST(TriangleBoxOverlap, AgreesWithDenseSamplingOnRandomTriangles) {
  // A sample point of the triangle strictly inside the box proves overlap; and when the test
  // says "overlap", some sample must lie within the sampling step of the box, because every
  // point of the triangle is within step = longest edge / kSteps of a sample.
  constexpr int kSteps = 60;
  std::mt19937 random(7);
  std::uniform_real_distribution<double> coordinate(-2.5, 2.5);
  const Eigen::Vector3d c(0.1, -0.2, 0.3);
  const Eigen::Vector3d e(1.0, 0.5, 0.8);
  int overlaps = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    Eigen::Vector3d v[3];
    for (auto& p : v) p = Eigen::Vector3d(coordinate(random), coordinate(random), coordinate(random));
    const double step = std::max({(v[1] - v[0]).norm(), (v[2] - v[1]).norm(),
                                  (v[0] - v[2]).norm()}) / kSteps;
    bool sampleInside = false, sampleNear = false;
    for (int i = 0; i <= kSteps; ++i) {
      for (int j = 0; i + j <= kSteps; ++j) {
        const Eigen::Vector3d p =
            v[0] + (v[1] - v[0]) * (double(i) / kSteps) + (v[2] - v[0]) * (double(j) / kSteps);
        const Eigen::Vector3d d = ((p - c).cwiseAbs() - e);
        sampleInside |= (d.array() < 0.0).all();
        sampleNear |= (d.array() <= step).all();
      }
    }
    const bool overlap = detail::triangleBoxOverlap(c, e, v[0], v[1], v[2]);
    overlaps += overlap;
    if (sampleInside) {
      EXPECT_TRUE(overlap) << "trial " << trial;
    }
    if (overlap) {
      EXPECT_TRUE(sampleNear) << "trial " << trial;
    }
  }
  // Both outcomes occur often enough for the checks to mean something.
  EXPECT_GT(overlaps, 200);
  EXPECT_LT(overlaps, 1800);
}

TEST(Voxelize, StanfordBunnyAtResolution30) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const TriMesh bunny = loadMesh(kBunnyPath);
  const auto start = std::chrono::steady_clock::now();
  const Voxelization v = voxelize(bunny, withResolution(30));
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  const double exact = signedVolume(bunny);
  const double error = (filledVolume(v) - exact) / exact;
  std::cout << "[ bunny    ] resolution 30: dims " << v.dims.transpose() << ", " << v.cells.size()
            << " cells, filled volume " << filledVolume(v) << " vs " << exact << " ("
            << error << "), " << ms << " ms\n";
  expectWellFormed(v);
  EXPECT_TRUE(v.closed);
  EXPECT_TRUE(v.warnings.empty());
  // The bunny is 2 x 1.98 x 1.55 units, so h = 2/30 and the lattice is 30 x 30 x 24.
  EXPECT_EQ(v.dims, Eigen::Vector3i(30, 30, 24));
  // Measured: 6,612 cells. The solid alone is volume / h^3 = 1.60 / (2/30)^3 = 5,400 cells; the
  // rest are partly filled surface cells. +-2% allows for changes in the surface-cell rule's
  // rounding without letting a real change (e.g. touching cells counted, about +10%) pass.
  EXPECT_GT(v.cells.size(), 6480u);
  EXPECT_LT(v.cells.size(), 6745u);
  // Occupied cells cover the solid (slivers under 1/64 of a cell aside), and the filled volume
  // matches the mesh's to sampling accuracy, as for the sphere.
  EXPECT_GE(v.cells.size() * std::pow(v.spacing, 3), exact);
  EXPECT_LT(std::abs(error), 0.01);
  EXPECT_EQ(countComponents(v.cells), 1);
}

}  // namespace
}  // namespace deformable_flsm

// The box of tests and benchmarks: every cell full, in (k, j, i) order, at the origin given.
TEST(BoxVoxels, FullCellsInSliceOrder) {
  const deformable_flsm::Voxelization v = deformable_flsm::boxVoxels(Eigen::Vector3i(3, 2, 4), 0.5, Eigen::Vector3d(1, 2, 3));
  ASSERT_EQ(v.cells.size(), 24u);
  EXPECT_EQ(v.fillFraction, std::vector<double>(24, 1.0));
  EXPECT_TRUE(v.closed);
  EXPECT_EQ(v.dims, Eigen::Vector3i(3, 2, 4));
  EXPECT_EQ(v.spacing, 0.5);
  EXPECT_EQ(v.origin, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(v.cells[1], Eigen::Vector3i(1, 0, 0));
  EXPECT_EQ(v.cells[3], Eigen::Vector3i(0, 1, 0));
  EXPECT_EQ(v.cells[6], Eigen::Vector3i(0, 0, 1));
  EXPECT_EQ(v.cells.back(), Eigen::Vector3i(2, 1, 3));
}
