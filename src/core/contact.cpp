#include "deformable_flsm/core/contact.h"

#include "deformable_flsm/core/mesh_distance_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace deformable_flsm {

namespace {

/// Distance to the box |p_a| <= e_a: outside, the distance to the nearest surface point; inside,
/// minus the distance to the nearest face.
double boxDistance(const Eigen::Vector3d& e, const Eigen::Vector3d& p, Eigen::Vector3d& normal) {
  const Eigen::Vector3d q = p.cwiseAbs() - e;
  const Eigen::Vector3d outside = q.cwiseMax(0.0);
  const double gap = outside.norm();
  if (gap > 0.0) {
    for (int a = 0; a < 3; ++a) normal[a] = std::copysign(outside[a], p[a]) / gap;
    return gap;
  }
  int axis = 0;
  q.maxCoeff(&axis);
  normal.setZero();
  normal[axis] = p[axis] < 0.0 ? -1.0 : 1.0;
  return q[axis];
}

/// Distance to the ball of `radius` around c (p - c given).
double ballDistance(const Eigen::Vector3d& d, double radius, Eigen::Vector3d& normal) {
  const double len = d.norm();
  normal = len > 0.0 ? Eigen::Vector3d(d / len) : Eigen::Vector3d::UnitZ();
  return len - radius;
}

/// Distance to the capped cylinder x^2 + y^2 <= R^2, |z| <= H: with the radial and axial
/// excesses q = (rho - R, |z| - H), rho = sqrt(x^2 + y^2), outside it is |max(q, 0)| (the nearest
/// point is on the side, on an end disc or on a rim), inside max(q_r, q_z) (the nearer of the side
/// and the end face).
double cylinderDistance(double R, double H, const Eigen::Vector3d& p, Eigen::Vector3d& normal) {
  const double rho = std::hypot(p.x(), p.y());
  // the outward radial direction; on the axis any is nearest
  const Eigen::Vector3d radial =
      rho > 0.0 ? Eigen::Vector3d(p.x() / rho, p.y() / rho, 0.0) : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d axial(0.0, 0.0, p.z() < 0.0 ? -1.0 : 1.0);
  const double qr = rho - R, qz = std::abs(p.z()) - H;
  if (qr > 0.0 || qz > 0.0) {
    const double a = std::max(qr, 0.0), b = std::max(qz, 0.0);
    const double gap = std::hypot(a, b);
    normal = (a * radial + b * axial) / gap;
    return gap;
  }
  normal = qr > qz ? radial : axial;
  return std::max(qr, qz);
}

}  // namespace

double shapeDistance(const ColliderShape& shape, const Eigen::Vector3d& p, Eigen::Vector3d& normal) {
  switch (shape.type) {
    case ColliderType::HalfSpace:
      normal = Eigen::Vector3d::UnitZ();
      return p.z();
    case ColliderType::Box:
      return boxDistance(shape.halfExtents, p, normal);
    case ColliderType::Sphere:
      return ballDistance(p, shape.radius, normal);
    case ColliderType::Capsule: {
      const double z = std::clamp(p.z(), -shape.halfLength, shape.halfLength);
      const double d = ballDistance(p - Eigen::Vector3d(0.0, 0.0, z), shape.radius, normal);
      // on the axis itself: any radial direction is nearest
      if (normal == Eigen::Vector3d::UnitZ() && p.z() == z && std::abs(z) < shape.halfLength)
        normal = Eigen::Vector3d::UnitX();
      return d;
    }
    case ColliderType::Cylinder:
      return cylinderDistance(shape.radius, shape.halfLength, p, normal);
    case ColliderType::Mesh:
      if (!shape.distanceField)
        throw std::invalid_argument("mesh collider without its distance field (Solver::setCollider builds it)");
      return shape.distanceField->distance(p, normal);
  }
  normal = Eigen::Vector3d::UnitZ();
  return std::numeric_limits<double>::infinity();
}

double colliderDistance(const ColliderShape& shape, const Eigen::Isometry3d& pose, const Eigen::Vector3d& x,
                        Eigen::Vector3d& normal) {
  if (shape.type == ColliderType::HalfSpace) {  // the common ground: one dot product
    normal = pose.linear().col(2);
    return normal.dot(x - pose.translation());
  }
  const Eigen::Matrix3d R = pose.linear();
  const Eigen::Vector3d local = R.transpose() * (x - pose.translation());
  Eigen::Vector3d n;
  const double d = shapeDistance(shape, local, n);
  normal = R * n;
  return d;
}

bool colliderBounds(const ColliderShape& shape, const Eigen::Isometry3d& pose, Eigen::Vector3d& lo,
                    Eigen::Vector3d& hi) {
  Eigen::Vector3d localLo = Eigen::Vector3d::Zero(), localHi = Eigen::Vector3d::Zero();
  switch (shape.type) {
    case ColliderType::HalfSpace:
      return false;
    case ColliderType::Box:
      localHi = shape.halfExtents;
      break;
    case ColliderType::Sphere:
      localHi.setConstant(shape.radius);
      break;
    case ColliderType::Capsule:
      localHi = Eigen::Vector3d(shape.radius, shape.radius, shape.radius + shape.halfLength);
      break;
    case ColliderType::Cylinder: {
      // Exact: along world axis i the cylinder of axis a (the frame's z) reaches
      // H |a_i| + R sqrt(1 - a_i^2) from its centre (the end discs' rims), tighter than the
      // rotated box around it for a tilted link.
      const Eigen::Vector3d a = pose.linear().col(2);
      const Eigen::Vector3d half =
          shape.halfLength * a.cwiseAbs() +
          shape.radius * (Eigen::Vector3d::Ones() - a.cwiseAbs2()).cwiseMax(0.0).cwiseSqrt();
      lo = pose.translation() - half;
      hi = pose.translation() + half;
      return true;
    }
    case ColliderType::Mesh:
      if (shape.distanceField) {  // bounds kept by the field: no pass over the vertices
        localLo = shape.distanceField->meshMin();
        localHi = shape.distanceField->meshMax();
      } else if (shape.mesh) {
        localLo = shape.mesh->boundsMin();
        localHi = shape.mesh->boundsMax();
      } else {
        return false;
      }
      break;
  }
  if (shape.type != ColliderType::Mesh) localLo = -localHi;
  // the box of a rotated box: centre R c + t, half extents |R| e
  const Eigen::Vector3d centre = pose * (0.5 * (localLo + localHi));
  const Eigen::Vector3d half = pose.linear().cwiseAbs() * (0.5 * (localHi - localLo));
  lo = centre - half;
  hi = centre + half;
  return true;
}

bool boxNearCollider(const ColliderShape& shape, const Eigen::Isometry3d& pose, const Eigen::Vector3d& lo,
                     const Eigen::Vector3d& hi, double margin) {
  if (shape.type == ColliderType::HalfSpace) {
    // the corner of the box deepest along -n
    const Eigen::Vector3d n = pose.linear().col(2);
    Eigen::Vector3d corner;
    for (int a = 0; a < 3; ++a) corner[a] = n[a] > 0.0 ? lo[a] : hi[a];
    return n.dot(corner - pose.translation()) < margin;
  }
  Eigen::Vector3d clo, chi;
  if (!colliderBounds(shape, pose, clo, chi)) return true;
  return ((lo.array() - margin) <= chi.array()).all() && ((hi.array() + margin) >= clo.array()).all();
}

Eigen::Isometry3d advancePose(const Eigen::Isometry3d& pose, const Eigen::Vector3d& linearVelocity,
                              const Eigen::Vector3d& angularVelocity, double t) {
  Eigen::Isometry3d out = pose;
  out.translation() += t * linearVelocity;
  const double angle = angularVelocity.norm() * t;
  if (angle != 0.0)
    out.linear() = Eigen::AngleAxisd(angle, angularVelocity.normalized()).toRotationMatrix() * pose.linear();
  return out;
}

std::size_t projectOutOfColliders(std::vector<Eigen::Vector3d>& points,
                                  const std::map<std::string, Collider>& colliders, double margin) {
  if (!std::isfinite(margin) || margin < 0.0)
    throw std::invalid_argument("projectOutOfColliders: margin must be finite and >= 0 (m)");
  if (points.empty()) return 0;
  Eigen::Vector3d lo = points[0], hi = points[0];
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  std::vector<char> moved(points.size(), 0);
  for (const auto& entry : colliders) {
    const Collider& c = entry.second;
    if (!boxNearCollider(c.shape, c.pose, lo, hi, margin)) continue;
    ColliderShape shape = c.shape;
    if (shape.type == ColliderType::Mesh && !shape.distanceField && shape.mesh)
      shape.distanceField = std::make_shared<const MeshDistanceField>(*shape.mesh);
    Eigen::Vector3d clo = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
    Eigen::Vector3d chi = -clo;
    if (colliderBounds(shape, c.pose, clo, chi)) {
      clo.array() -= margin;
      chi.array() += margin;
    }
    for (std::size_t v = 0; v < points.size(); ++v) {
      Eigen::Vector3d& p = points[v];
      if ((p.array() < clo.array()).any() || (p.array() > chi.array()).any()) continue;
      Eigen::Vector3d n;
      const double d = colliderDistance(shape, c.pose, p, n) - margin;
      if (d < 0.0) {
        p -= d * n;
        moved[v] = 1;
      }
    }
  }
  return static_cast<std::size_t>(std::count(moved.begin(), moved.end(), 1));
}

}  // namespace deformable_flsm
