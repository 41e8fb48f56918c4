// bench_camera: what a depth camera frame costs (runtime/scene_renderer.h): depth, colour and
// labels at 640 x 480 (and 320 x 240), one thread, for the default scene (the bunny's full render
// mesh, 69,666 triangles, on the ground) and for bins of 20 and 150 bunnies of 800 triangles in a
// box of five box colliders. Each frame moves every vertex (a deforming object: the BVH is
// refitted) and renders; the figures are the median (and 95th percentile) over the frames of the
// wall time, and the median of the process's CPU time (what a frame costs the core on a machine
// shared with other work, where the wall time also counts the waits), ms.
//
//   bench_camera [--frames N] [--scene default|bin20|bin150] [--width W --height H]
#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/runtime/camera_spec.h"
#include "deformable_flsm/runtime/render_mesh.h"
#include "deformable_flsm/runtime/scene_renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

CameraIntrinsics camera(int width, int height) {
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = 0.5 * width / std::tan(0.5 * 60.0 * M_PI / 180.0);
  c.cx = 0.5 * (width - 1);
  c.cy = 0.5 * (height - 1);
  return c;
}

Collider boxAt(const Eigen::Vector3d& at, const Eigen::Vector3d& size) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = 0.5 * size;
  c.pose = Eigen::Translation3d(at) * Eigen::Isometry3d::Identity();
  return c;
}

struct Scene {
  std::string name;
  std::vector<TriMesh> meshes;  // at rest
  std::map<std::string, Collider> colliders;
  Eigen::Isometry3d eye;
};

TriMesh standingBunny(double scale, std::size_t triangles) {
  TriMesh m = loadMesh(kBunnyMeshPath, scale);
  rotateMesh(Eigen::Vector3d(M_PI / 2.0, 0.0, 0.0), m);
  if (triangles > 0) m = simplifyMesh(m, triangles).mesh;
  // on z = 0, centred in x and y
  const Eigen::Vector3d lo = m.boundsMin(), hi = m.boundsMax();
  const Eigen::Vector3d shift(-0.5 * (lo.x() + hi.x()), -0.5 * (lo.y() + hi.y()), -lo.z());
  for (Eigen::Vector3d& v : m.vertices) v += shift;
  return m;
}

Scene defaultScene() {
  Scene s;
  s.name = "default: the bunny (full mesh) on the ground";
  s.meshes.push_back(standingBunny(0.1, 0));
  Collider ground;
  ground.shape.type = ColliderType::HalfSpace;
  s.colliders["ground"] = ground;
  s.eye = opticalLookAt(Eigen::Vector3d(0.45, -0.3, 0.35), Eigen::Vector3d(0.0, 0.0, 0.1));
  return s;
}

Scene binScene(int n) {
  Scene s;
  s.name = "bin of " + std::to_string(n) + " bunnies of 800 triangles";
  const TriMesh bunny = standingBunny(0.045, 800);
  const int across = static_cast<int>(std::ceil(std::sqrt(n / 3.0)));
  const double pitch = 0.12, half = 0.5 * across * pitch;
  for (int k = 0; k < n; ++k) {
    TriMesh m = bunny;
    const Eigen::Vector3d at(-half + pitch * (0.5 + k % across), -half + pitch * (0.5 + (k / across) % across),
                             0.1 * (k / (across * across)));
    for (Eigen::Vector3d& v : m.vertices) v += at;
    s.meshes.push_back(std::move(m));
  }
  const double w = 2.0 * half + 0.1;
  s.colliders["floor"] = boxAt(Eigen::Vector3d(0, 0, -0.025), Eigen::Vector3d(w, w, 0.05));
  s.colliders["wall_e"] = boxAt(Eigen::Vector3d(half + 0.025, 0, 0.175), Eigen::Vector3d(0.05, w, 0.35));
  s.colliders["wall_w"] = boxAt(Eigen::Vector3d(-half - 0.025, 0, 0.175), Eigen::Vector3d(0.05, w, 0.35));
  s.colliders["wall_n"] = boxAt(Eigen::Vector3d(0, half + 0.025, 0.175), Eigen::Vector3d(w, 0.05, 0.35));
  s.colliders["wall_s"] = boxAt(Eigen::Vector3d(0, -half - 0.025, 0.175), Eigen::Vector3d(w, 0.05, 0.35));
  s.eye = opticalLookAt(Eigen::Vector3d(0.0, -0.35 - half, 0.5 + half), Eigen::Vector3d(0.0, 0.0, 0.05));
  return s;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

double cpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * (v.size() - 1))];
}

void run(const Scene& scene, int width, int height, int frames) {
  SceneRenderer renderer;
  std::vector<std::vector<Eigen::Vector3d>> vertices;
  std::size_t triangles = 0;
  for (const TriMesh& m : scene.meshes) {
    vertices.push_back(m.vertices);
    triangles += m.triangles.size();
  }
  const CameraIntrinsics cam = camera(width, height);
  RenderedView view;
  std::vector<double> ms, cpu;
  std::size_t seen = 0;
  for (int f = 0; f < frames + 2; ++f) {
    // every vertex moves, as a deforming object's do
    const double wobble = 0.002 * std::sin(0.7 * f);
    for (std::size_t k = 0; k < vertices.size(); ++k)
      for (std::size_t i = 0; i < vertices[k].size(); ++i)
        vertices[k][i] = scene.meshes[k].vertices[i] * (1.0 + wobble);
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = cpuSeconds();
    std::vector<SceneRenderer::Object> objects;
    for (std::size_t k = 0; k < vertices.size(); ++k)
      objects.push_back({&scene.meshes[k].triangles, &vertices[k], Eigen::Vector3f(0.85f, 0.72f, 0.55f)});
    renderer.setObjects(objects);
    renderer.setColliders(scene.colliders);
    renderer.render(cam, scene.eye, view);
    const double c1 = cpuSeconds();
    const auto t1 = std::chrono::steady_clock::now();
    if (f >= 2) {  // 2 warm-up frames
      ms.push_back(1e3 * std::chrono::duration<double>(t1 - t0).count());
      cpu.push_back(1e3 * (c1 - c0));
    }
    seen = 0;
    for (std::uint16_t l : view.label) seen += l > 0 && l < SceneRenderer::kFirstCollider;
  }
  std::printf("%-48s %4d x %-4d %8zu %7.1f %%  %8.2f %8.2f %8.2f\n", scene.name.c_str(), width, height,
              triangles, 100.0 * seen / view.label.size(), percentile(ms, 0.5), percentile(ms, 0.95),
              percentile(cpu, 0.5));
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 30, width = 0, height = 0;
  std::string only;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--frames") == 0) frames = std::max(1, std::atoi(argv[i + 1]));
    if (std::strcmp(argv[i], "--scene") == 0) only = argv[i + 1];
    if (std::strcmp(argv[i], "--width") == 0) width = std::atoi(argv[i + 1]);
    if (std::strcmp(argv[i], "--height") == 0) height = std::atoi(argv[i + 1]);
  }
  std::printf("bench_camera: depth + rgb + labels per frame, one thread, %d frames; CPU: %s\n", frames,
              cpuModel().c_str());
  std::printf("%-48s %11s %8s %9s  %8s %8s %8s\n", "scene", "pixels", "tris", "objects", "median", "p95 ms",
              "cpu ms");
  const std::map<std::string, Scene (*)()> scenes = {{"default", defaultScene},
                                                      {"bin20", [] { return binScene(20); }},
                                                      {"bin150", [] { return binScene(150); }}};
  for (const char* name : {"default", "bin20", "bin150"}) {
    if (!only.empty() && only != name) continue;
    const Scene s = scenes.at(name)();
    if (width > 0 && height > 0) {
      run(s, width, height, frames);
    } else {
      run(s, 640, 480, frames);
      run(s, 320, 240, frames);
    }
  }
  if (!only.empty() && scenes.count(only) == 0) {
    std::fprintf(stderr, "bench_camera: no scene '%s' (default, bin20, bin150)\n", only.c_str());
    return 2;
  }
  return 0;
}
