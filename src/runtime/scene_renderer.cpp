/// @file scene_renderer.cpp
/// SceneRenderer: Embree scenes for the objects and the colliders, and the camera's rays.
#include "deformable_flsm/runtime/scene_renderer.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

namespace {

constexpr double kPi = 3.14159265358979323846;
/// Segments around a tessellated circle: a chord deviates from the arc by r (1 - cos(pi / n)),
/// 0.05 % of the radius.
constexpr int kRound = 96;
/// Rings of a capsule's hemispherical end (pole to equator).
constexpr int kRings = 24;
/// Colours (0..1): colliders grey, a plane (the ground, walls) lighter.
const Eigen::Vector3f kColliderColor(0.55f, 0.57f, 0.62f);
const Eigen::Vector3f kPlaneColor(0.75f, 0.75f, 0.72f);
/// Shading: ambient light and the headlight's share (by the cosine between normal and ray).
constexpr float kAmbient = 0.25f;
constexpr float kHeadlight = 0.75f;
/// Rays go in packets of kTile x kTile pixels (Embree's 16-wide packets).
constexpr int kTile = 4;

using Triangles = std::vector<std::array<std::uint32_t, 3>>;

/// A shape's triangles in its own frame.
struct Tessellation {
  std::vector<Eigen::Vector3f> vertices;
  Triangles triangles;
  std::uint32_t add(const Eigen::Vector3d& v) {
    vertices.push_back(v.cast<float>());
    return static_cast<std::uint32_t>(vertices.size() - 1);
  }
  void tri(std::uint32_t a, std::uint32_t b, std::uint32_t c) { triangles.push_back({a, b, c}); }
  void quad(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    tri(a, b, c);
    tri(a, c, d);
  }
};

Tessellation box(const Eigen::Vector3d& h) {
  Tessellation t;
  for (int k = 0; k < 8; ++k)
    t.add(Eigen::Vector3d((k & 1) ? h.x() : -h.x(), (k & 2) ? h.y() : -h.y(), (k & 4) ? h.z() : -h.z()));
  t.quad(0, 2, 3, 1);  // -z
  t.quad(4, 5, 7, 6);  // +z
  t.quad(0, 1, 5, 4);  // -y
  t.quad(2, 6, 7, 3);  // +y
  t.quad(0, 4, 6, 2);  // -x
  t.quad(1, 3, 7, 5);  // +x
  return t;
}

/// A ring of kRound vertices of radius r at height z; returns the first index.
std::uint32_t ring(Tessellation& t, double r, double z) {
  const std::uint32_t first = static_cast<std::uint32_t>(t.vertices.size());
  for (int k = 0; k < kRound; ++k) {
    const double a = 2.0 * kPi * k / kRound;
    t.add(Eigen::Vector3d(r * std::cos(a), r * std::sin(a), z));
  }
  return first;
}

void band(Tessellation& t, std::uint32_t lower, std::uint32_t upper) {
  for (int k = 0; k < kRound; ++k) {
    const std::uint32_t k1 = static_cast<std::uint32_t>((k + 1) % kRound);
    t.quad(lower + k, lower + k1, upper + k1, upper + k);
  }
}

void fan(Tessellation& t, std::uint32_t rim, const Eigen::Vector3d& centre, bool up) {
  const std::uint32_t c = t.add(centre);
  for (int k = 0; k < kRound; ++k) {
    const std::uint32_t k1 = static_cast<std::uint32_t>((k + 1) % kRound);
    if (up)
      t.tri(c, rim + k, rim + k1);
    else
      t.tri(c, rim + k1, rim + k);
  }
}

Tessellation cylinder(double r, double h) {
  Tessellation t;
  const std::uint32_t lo = ring(t, r, -h), hi = ring(t, r, h);
  band(t, lo, hi);
  fan(t, lo, Eigen::Vector3d(0, 0, -h), false);
  fan(t, hi, Eigen::Vector3d(0, 0, h), true);
  return t;
}

Tessellation capsule(double r, double h) {
  Tessellation t;
  // rings from the bottom pole's neighbour up to the top pole's
  std::vector<std::uint32_t> rings;
  for (int i = 1; i <= kRings; ++i) {  // lower hemisphere, pole to equator
    const double phi = 0.5 * kPi * i / kRings;
    rings.push_back(ring(t, r * std::sin(phi), -h - r * std::cos(phi)));
  }
  for (int i = kRings; i >= 1; --i) {  // upper hemisphere, equator to pole
    const double phi = 0.5 * kPi * i / kRings;
    rings.push_back(ring(t, r * std::sin(phi), h + r * std::cos(phi)));
  }
  for (std::size_t i = 0; i + 1 < rings.size(); ++i) band(t, rings[i], rings[i + 1]);
  fan(t, rings.front(), Eigen::Vector3d(0, 0, -h - r), false);
  fan(t, rings.back(), Eigen::Vector3d(0, 0, h + r), true);
  return t;
}

Tessellation meshOf(const TriMesh& mesh) {
  Tessellation t;
  for (const Eigen::Vector3d& v : mesh.vertices) t.add(v);
  t.triangles = mesh.triangles;
  return t;
}

bool sameShape(const ColliderShape& a, const ColliderShape& b) {
  return a.type == b.type && a.halfExtents == b.halfExtents && a.radius == b.radius &&
         a.halfLength == b.halfLength && a.mesh == b.mesh;
}

void check(RTCDevice device, const char* what) {
  const RTCError e = rtcGetDeviceError(device);
  if (e != RTC_ERROR_NONE)
    throw std::runtime_error(std::string("scene renderer: Embree failed to ") + what + " (error " +
                             std::to_string(static_cast<int>(e)) + ")");
}

RTCGeometry triangleGeometry(RTCDevice device, const std::vector<Eigen::Vector3f>& vertices,
                             const Triangles& triangles, RTCBuildQuality quality) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), vertices.size()));
  auto* i = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                3 * sizeof(std::uint32_t), triangles.size()));
  check(device, "make a triangle buffer");
  for (std::size_t k = 0; k < vertices.size(); ++k)
    for (int d = 0; d < 3; ++d) v[3 * k + d] = vertices[k][d];
  for (std::size_t k = 0; k < triangles.size(); ++k)
    for (int d = 0; d < 3; ++d) i[3 * k + d] = triangles[k][d];
  rtcSetGeometryBuildQuality(g, quality);
  rtcCommitGeometry(g);
  return g;
}

/// Whether any ray of a packet (from `o`, up to its tfar) may meet the box `b`: packets that
/// see only the planes (most of a view of the ground) skip Embree's call and its traversal.
bool mayHit(const RTCBounds& b, const Eigen::Vector3f& o, const RTCRay16& ray) {
  if (!(b.lower_x <= b.upper_x)) return false;  // nothing in the scene
  const float lo[3] = {b.lower_x - o.x(), b.lower_y - o.y(), b.lower_z - o.z()};
  const float hi[3] = {b.upper_x - o.x(), b.upper_y - o.y(), b.upper_z - o.z()};
  bool any = false;
  for (int i = 0; i < 16; ++i) {
    const float d[3] = {ray.dir_x[i], ray.dir_y[i], ray.dir_z[i]};
    float enter = ray.tnear[i], leave = ray.tfar[i];
    bool outside = false;
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0.0f) {  // parallel to the slab: always in it or never
        outside = outside || lo[a] > 0.0f || hi[a] < 0.0f;
        continue;
      }
      const float t1 = lo[a] / d[a], t2 = hi[a] / d[a];
      enter = std::max(enter, std::min(t1, t2));
      leave = std::min(leave, std::max(t1, t2));
    }
    any |= !outside && !(enter > leave);
  }
  return any;
}

}  // namespace

struct SceneRenderer::Impl {
  /// What a hit on a geometry of the top scene is.
  struct Hit {
    std::uint16_t label = kNothing;
    Eigen::Vector3f color = Eigen::Vector3f::Ones();
  };
  struct ObjectGeometry {
    RTCGeometry geometry = nullptr;
    unsigned id = RTC_INVALID_GEOMETRY_ID;
    const Triangles* triangles = nullptr;
    std::size_t vertexCount = 0;
  };
  /// A plane (the ground, a wall) is intersected by the rays directly, not through Embree, which
  /// every ray would otherwise traverse to its two triangles.
  struct Plane {
    Eigen::Vector3f normal;  // the plane's z axis
    float offset = 0.0f;     // normal . x on the plane
    Hit hit;
  };
  /// A collider's geometry in the top scene, in the simulation frame: moved by rewriting its
  /// vertices (a second level of instances costs every ray more than this costs a frame). A
  /// plane has none (see Plane).
  struct ColliderGeometry {
    ColliderShape shape;
    Tessellation local;  // in the collider's frame (a sphere: none)
    RTCGeometry geometry = nullptr;
    unsigned id = RTC_INVALID_GEOMETRY_ID;
    Eigen::Isometry3d pose;
    bool placed = false;  // its vertices are at `pose`
  };

  RTCDevice device = nullptr;
  RTCScene top = nullptr;
  std::vector<ObjectGeometry> objects;
  std::map<std::string, ColliderGeometry> colliders;
  std::vector<Hit> hits;  // by geometry id in the top scene
  std::vector<Plane> planes;
  std::vector<float> heights;  // render(): each plane's offset from the camera along its normal
  std::vector<Eigen::Vector3f> columns, rows;  // render(): the rays' directions by column and row

  Hit& hitOf(unsigned id) {
    if (hits.size() <= id) hits.resize(id + 1);
    return hits[id];
  }

  void dropObject(ObjectGeometry& o) {
    rtcDetachGeometry(top, o.id);
    rtcReleaseGeometry(o.geometry);
  }
  void dropCollider(ColliderGeometry& c) {
    if (c.geometry == nullptr) return;  // a plane
    rtcDetachGeometry(top, c.id);
    rtcReleaseGeometry(c.geometry);
  }

  /// Puts collider `c`'s geometry at `pose`.
  void place(ColliderGeometry& c, const Eigen::Isometry3d& pose) {
    if (c.placed && c.pose.isApprox(pose, 0.0)) return;
    c.pose = pose;
    c.placed = true;
    if (c.geometry == nullptr) return;  // a plane: its pose is all
    auto* p = static_cast<float*>(rtcGetGeometryBufferData(c.geometry, RTC_BUFFER_TYPE_VERTEX, 0));
    if (c.shape.type == ColliderType::Sphere) {
      for (int d = 0; d < 3; ++d) p[d] = static_cast<float>(pose.translation()[d]);
      p[3] = static_cast<float>(c.shape.radius);
    } else {
      const Eigen::Matrix3f R = pose.linear().cast<float>();
      const Eigen::Vector3f t = pose.translation().cast<float>();
      for (std::size_t k = 0; k < c.local.vertices.size(); ++k) {
        const Eigen::Vector3f x = R * c.local.vertices[k] + t;
        for (int d = 0; d < 3; ++d) p[3 * k + d] = x[d];
      }
    }
    rtcUpdateGeometryBuffer(c.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(c.geometry);
  }

  ColliderGeometry build(const ColliderShape& shape) {
    ColliderGeometry c;
    c.shape = shape;
    if (shape.type == ColliderType::HalfSpace) return c;
    if (shape.type == ColliderType::Sphere) {
      c.geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
      rtcSetNewGeometryBuffer(c.geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1);
      check(device, "make a sphere");
    } else {
      switch (shape.type) {
        case ColliderType::HalfSpace: break;
        case ColliderType::Box: c.local = box(shape.halfExtents); break;
        case ColliderType::Capsule: c.local = capsule(shape.radius, shape.halfLength); break;
        case ColliderType::Cylinder: c.local = cylinder(shape.radius, shape.halfLength); break;
        case ColliderType::Mesh: c.local = meshOf(*shape.mesh); break;
        case ColliderType::Sphere: break;
      }
      c.geometry = triangleGeometry(device, c.local.vertices, c.local.triangles, RTC_BUILD_QUALITY_REFIT);
    }
    c.id = rtcAttachGeometry(top, c.geometry);
    check(device, "build a collider");
    return c;
  }
  /// A packet's pixels from what its rays met (an Embree hit, a plane in plane[i], or nothing):
  /// depth, label and the headlight-shaded colour of tile (u0, v0) in an image w wide.
  void shade(const RTCRayHit16& rh, const int* valid, const int* plane, int u0, int v0, int w,
             RenderedView& out) const;
};

SceneRenderer::SceneRenderer() : impl_(std::make_unique<Impl>()) {
  // One thread: the node renders on a thread of its own, beside the simulation's.
  impl_->device = rtcNewDevice("threads=1,set_affinity=0");
  if (impl_->device == nullptr)
    throw std::runtime_error("scene renderer: Embree could not start (rtcNewDevice failed)");
  impl_->top = rtcNewScene(impl_->device);
  rtcSetSceneFlags(impl_->top, RTC_SCENE_FLAG_DYNAMIC);
  rtcSetSceneBuildQuality(impl_->top, RTC_BUILD_QUALITY_LOW);
}

SceneRenderer::~SceneRenderer() {
  for (auto& o : impl_->objects) impl_->dropObject(o);
  for (auto& entry : impl_->colliders) impl_->dropCollider(entry.second);
  rtcReleaseScene(impl_->top);
  rtcReleaseDevice(impl_->device);
}

void SceneRenderer::setObjects(const std::vector<Object>& objects) {
  Impl& m = *impl_;
  bool same = objects.size() == m.objects.size();
  for (std::size_t k = 0; same && k < objects.size(); ++k)
    same = objects[k].triangles == m.objects[k].triangles &&
           objects[k].vertices->size() == m.objects[k].vertexCount;
  if (!same) {
    for (auto& o : m.objects) m.dropObject(o);
    m.objects.clear();
  }
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const Object& o = objects[k];
    if (!same) {
      std::vector<Eigen::Vector3f> v(o.vertices->size());
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = (*o.vertices)[i].cast<float>();
      Impl::ObjectGeometry g;
      g.geometry = triangleGeometry(m.device, v, *o.triangles, RTC_BUILD_QUALITY_REFIT);
      g.id = rtcAttachGeometry(m.top, g.geometry);
      g.triangles = o.triangles;
      g.vertexCount = v.size();
      m.objects.push_back(g);
    } else {
      // straight into Embree's buffer: no copy of the mesh per frame
      RTCGeometry g = m.objects[k].geometry;
      auto* p = static_cast<float*>(rtcGetGeometryBufferData(g, RTC_BUFFER_TYPE_VERTEX, 0));
      const std::vector<Eigen::Vector3d>& x = *o.vertices;
      for (std::size_t i = 0; i < x.size(); ++i)
        for (int d = 0; d < 3; ++d) p[3 * i + d] = static_cast<float>(x[i][d]);
      rtcUpdateGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0);
      rtcCommitGeometry(g);
    }
    Impl::Hit& h = m.hitOf(m.objects[k].id);
    h.label = objectLabel(k);
    h.color = o.color;
  }
  check(m.device, "update the objects");
}

void SceneRenderer::setColliders(const std::map<std::string, Collider>& colliders) {
  Impl& m = *impl_;
  for (auto it = m.colliders.begin(); it != m.colliders.end();) {
    const auto now = colliders.find(it->first);
    if (now == colliders.end() || !sameShape(now->second.shape, it->second.shape)) {
      m.dropCollider(it->second);
      it = m.colliders.erase(it);
    } else {
      ++it;
    }
  }
  std::size_t i = 0;
  m.planes.clear();
  for (const auto& entry : colliders) {
    auto it = m.colliders.find(entry.first);
    if (it == m.colliders.end()) it = m.colliders.emplace(entry.first, m.build(entry.second.shape)).first;
    Impl::ColliderGeometry& c = it->second;
    m.place(c, entry.second.pose);
    const std::uint16_t label = colliderLabel(i++);
    if (c.geometry == nullptr) {
      Impl::Plane plane;
      plane.normal = c.pose.linear().col(2).cast<float>();
      plane.offset = plane.normal.dot(c.pose.translation().cast<float>());
      plane.hit.label = label;
      plane.hit.color = kPlaneColor;
      m.planes.push_back(plane);
      continue;
    }
    Impl::Hit& h = m.hitOf(c.id);
    h.label = label;
    h.color = kColliderColor;
  }
  check(m.device, "update the colliders");
}

void SceneRenderer::Impl::shade(const RTCRayHit16& rh, const int* valid, const int* plane, int u0, int v0, int w,
                                RenderedView& out) const {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < 16; ++i) {
    if (!valid[i]) continue;
    const int u = u0 + i % kTile, v = v0 + i / kTile;
    const std::size_t p = static_cast<std::size_t>(v) * w + u;
    std::uint8_t* rgb = &out.rgb[3 * p];
    const bool embree = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    if (!embree && plane[i] < 0) {
      out.depth[p] = nan;
      out.label[p] = kNothing;
      rgb[0] = rgb[1] = rgb[2] = 0;
      continue;
    }
    const Impl::Hit& hit = embree ? hits[rh.hit.geomID[i]] : planes[plane[i]].hit;
    const Eigen::Vector3f n = embree ? Eigen::Vector3f(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i])
                                     : planes[plane[i]].normal;
    const Eigen::Vector3f d(rh.ray.dir_x[i], rh.ray.dir_y[i], rh.ray.dir_z[i]);
    out.depth[p] = rh.ray.tfar[i];
    out.label[p] = hit.label;
    const float nn = n.squaredNorm() * d.squaredNorm();
    const float cosine = nn > 0.0f ? std::abs(n.dot(d)) / std::sqrt(nn) : 1.0f;
    const Eigen::Vector3f c = hit.color * (255.0f * (kAmbient + kHeadlight * cosine));
    for (int k = 0; k < 3; ++k) rgb[k] = static_cast<std::uint8_t>(std::min(255.0f, c[k]) + 0.5f);
  }
}

void SceneRenderer::render(const CameraIntrinsics& camera, const Eigen::Isometry3d& cameraPose,
                           RenderedView& out) {
  Impl& m = *impl_;
  rtcCommitScene(m.top);
  check(m.device, "build the scene");
  const int w = camera.width, h = camera.height;
  out.width = w;
  out.height = h;
  // every pixel is written below, hit or not: no clearing pass
  out.depth.resize(static_cast<std::size_t>(w) * h);
  out.rgb.resize(static_cast<std::size_t>(w) * h * 3);
  out.label.resize(static_cast<std::size_t>(w) * h);
  const Eigen::Matrix3f R = cameraPose.linear().cast<float>();
  const Eigen::Vector3f o = cameraPose.translation().cast<float>();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  // A ray's direction R (x, y, 1) (z = 1 in the optical frame: the ray's parameter is the
  // depth) is a column's part plus a row's, each computed once.
  m.columns.resize(w);
  m.rows.resize(h);
  for (int u = 0; u < w; ++u) m.columns[u] = R.col(0) * static_cast<float>((u - camera.cx) / camera.fx);
  for (int v = 0; v < h; ++v) m.rows[v] = R.col(1) * static_cast<float>((v - camera.cy) / camera.fy) + R.col(2);
  const float tnear = static_cast<float>(camera.near), tfar = static_cast<float>(camera.far);
  RTCBounds bounds;  // of what Embree holds (empty: lower above upper)
  rtcGetSceneBounds(m.top, &bounds);
  // the planes' distance along their normal from the camera
  const std::size_t planes = m.planes.size();
  m.heights.resize(planes);
  for (std::size_t k = 0; k < planes; ++k) m.heights[k] = m.planes[k].offset - m.planes[k].normal.dot(o);
  alignas(64) RTCRayHit16 rh;
  alignas(64) int valid[16];
  alignas(64) int plane[16];  // the plane a ray meets first, or -1
  for (int i = 0; i < 16; ++i) {
    rh.ray.org_x[i] = o.x();
    rh.ray.org_y[i] = o.y();
    rh.ray.org_z[i] = o.z();
    rh.ray.mask[i] = 0xFFFFFFFFu;
    rh.ray.flags[i] = 0;
    rh.ray.time[i] = 0.0f;
  }
  // Tiles of 4 x 4 pixels as one packet of 16 rays: neighbouring rays share their way through
  // the BVH. The planes come first: Embree then looks only for what lies nearer.
  for (int v0 = 0; v0 < h; v0 += kTile) {
    for (int u0 = 0; u0 < w; u0 += kTile) {
      for (int i = 0; i < 16; ++i) {
        const int u = u0 + i % kTile, v = v0 + i / kTile;
        valid[i] = u < w && v < h ? -1 : 0;
        const Eigen::Vector3f d = m.columns[std::min(u, w - 1)] + m.rows[std::min(v, h - 1)];
        rh.ray.dir_x[i] = d.x();
        rh.ray.dir_y[i] = d.y();
        rh.ray.dir_z[i] = d.z();
        rh.ray.tnear[i] = tnear;
        float t = tfar;
        plane[i] = -1;
        for (std::size_t k = 0; k < planes; ++k) {
          const float along = m.planes[k].normal.dot(d);
          const float at = m.heights[k] / along;  // +-inf or NaN when parallel: compared false below
          if (at >= tnear && at < t) {
            t = at;
            plane[i] = static_cast<int>(k);
          }
        }
        rh.ray.tfar[i] = t;
        rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
      }
      // without planes a packet that meets nothing costs Embree no more than the test would
      if (planes == 0 || mayHit(bounds, o, rh.ray)) rtcIntersect16(valid, m.top, &context, &rh);
      m.shade(rh, valid, plane, u0, v0, w, out);
    }
  }
}

}  // namespace deformable_flsm
