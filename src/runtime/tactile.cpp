#include "deformable_flsm/runtime/tactile.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace deformable_flsm {

bool parseFace(const std::string& face, int& axis, int& sign) {
  if (face.size() != 2 || (face[0] != '+' && face[0] != '-') || face[1] < 'x' || face[1] > 'z') return false;
  sign = face[0] == '+' ? 1 : -1;
  axis = face[1] - 'x';
  return true;
}

int tactileColumnAxis(const TactileSpec& spec) { return (spec.axis + (spec.sign > 0 ? 1 : 2)) % 3; }

int tactileRowAxis(const TactileSpec& spec) { return (spec.axis + (spec.sign > 0 ? 2 : 1)) % 3; }

std::string faceName(int axis, int sign) {
  return std::string(1, sign > 0 ? '+' : '-') + static_cast<char>('x' + axis);
}

void tactileImage(const TactileSpec& spec, const Collider& box, const std::vector<ParticleContact>& contacts,
                  TactileImage& out) {
  if (box.shape.type != ColliderType::Box)
    throw std::invalid_argument("tactile sensor '" + spec.name + "': collider '" + spec.collider + "' is a " +
                                toString(box.shape.type) + ", not a box");
  const int a = spec.axis, u = tactileColumnAxis(spec), v = tactileRowAxis(spec);
  const Eigen::Vector3d& h = box.shape.halfExtents;
  out.rows = spec.rows;
  out.cols = spec.cols;
  out.taxelArea = (2.0 * h[u] / spec.cols) * (2.0 * h[v] / spec.rows);
  out.pressure.assign(static_cast<std::size_t>(spec.rows) * spec.cols, 0.0f);
  out.shear.assign(2 * out.pressure.size(), 0.0f);
  out.normalForce = 0.0;
  out.shearForce.setZero();
  out.elsewhere.setZero();
  const Eigen::Matrix3d Rt = box.pose.linear().transpose();
  for (const ParticleContact& c : contacts) {
    const Eigen::Vector3d q = Rt * (c.point - box.pose.translation());
    const Eigen::Vector3d f = Rt * c.force;  // in the collider's frame
    if (!(spec.sign * q[a] > 0.0)) {
      out.elsewhere += c.force;
      continue;
    }
    const int col = std::clamp(static_cast<int>(std::floor((q[u] + h[u]) / (2.0 * h[u]) * spec.cols)), 0, spec.cols - 1);
    const int row = std::clamp(static_cast<int>(std::floor((q[v] + h[v]) / (2.0 * h[v]) * spec.rows)), 0, spec.rows - 1);
    const std::size_t t = static_cast<std::size_t>(row) * spec.cols + col;
    const double normal = -spec.sign * f[a];  // pushing into the face
    out.pressure[t] += static_cast<float>(normal / out.taxelArea);
    out.shear[2 * t] += static_cast<float>(f[u] / out.taxelArea);
    out.shear[2 * t + 1] += static_cast<float>(f[v] / out.taxelArea);
    out.normalForce += normal;
    out.shearForce += Eigen::Vector2d(f[u], f[v]);
  }
}

}  // namespace deformable_flsm
