#include "deformable_flsm/core/collider.h"

#include "number_text.h"

#include <cmath>
#include <string>
#include <stdexcept>

namespace deformable_flsm {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("collider: " + what); }

}  // namespace

ColliderType parseColliderType(const std::string& name) {
  if (name == "plane" || name == "half_space") return ColliderType::HalfSpace;
  if (name == "box") return ColliderType::Box;
  if (name == "sphere") return ColliderType::Sphere;
  if (name == "capsule") return ColliderType::Capsule;
  if (name == "cylinder") return ColliderType::Cylinder;
  if (name == "mesh") return ColliderType::Mesh;
  throw std::invalid_argument("unknown collider type '" + name +
                              "': expected plane (or half_space), box, sphere, capsule, cylinder or mesh");
}

const char* toString(ColliderType type) {
  switch (type) {
    case ColliderType::HalfSpace: return "plane";
    case ColliderType::Box: return "box";
    case ColliderType::Sphere: return "sphere";
    case ColliderType::Capsule: return "capsule";
    case ColliderType::Cylinder: return "cylinder";
    case ColliderType::Mesh: return "mesh";
  }
  return "?";
}

void ColliderShape::validate() const {
  const std::string name = toString(type);
  switch (type) {
    case ColliderType::HalfSpace:
      break;
    case ColliderType::Box:
      if (!halfExtents.allFinite() || (halfExtents.array() <= 0.0).any())
        fail("box half extents [" + numberText(halfExtents.x()) + ", " + numberText(halfExtents.y()) + ", " +
             numberText(halfExtents.z()) + "]: expected three finite lengths > 0 (m)");
      break;
    case ColliderType::Sphere:
    case ColliderType::Capsule:
      if (!std::isfinite(radius) || radius <= 0.0)
        fail(name + " radius " + numberText(radius) + ": expected a finite radius > 0 (m)");
      if (type == ColliderType::Capsule && (!std::isfinite(halfLength) || halfLength < 0.0))
        fail("capsule half length " + numberText(halfLength) + ": expected a finite length >= 0 (m)");
      break;
    case ColliderType::Cylinder:
      if (!std::isfinite(radius) || radius <= 0.0)
        fail("cylinder radius " + numberText(radius) + ": expected a finite radius > 0 (m)");
      if (!std::isfinite(halfLength) || halfLength <= 0.0)
        fail("cylinder half length " + numberText(halfLength) + ": expected a finite length > 0 (m)");
      break;
    case ColliderType::Mesh:
      if (!mesh) fail("mesh collider without a mesh: load one (loadMesh) and set shape.mesh");
      if (mesh->triangles.empty() || mesh->vertices.empty())
        fail("mesh collider: the mesh has no triangles");
      try {
        validateMesh(*mesh, "mesh collider");
      } catch (const MeshError& e) {
        fail(e.what());
      }
      // the distance field tells inside from outside by ray parity: it needs a closed surface
      if (const std::size_t open = countBoundaryEdges(*mesh))
        fail("mesh collider: the mesh has " + std::to_string(open) +
             " open edges; a collider needs a closed mesh (a solid) to tell inside from outside");
      break;
  }
}

void Collider::validate() const {
  shape.validate();
  if (!pose.matrix().allFinite()) fail("pose has non-finite entries");
  const Eigen::Matrix3d R = pose.linear();
  if (!(R.transpose() * R).isIdentity(1e-6) || R.determinant() < 0.0)
    fail("pose rotation is not a rotation (orthonormal, determinant +1)");
  if (!linearVelocity.allFinite()) fail("linear velocity has non-finite entries");
  if (!angularVelocity.allFinite()) fail("angular velocity has non-finite entries");
  if (!std::isfinite(staticFriction) || staticFriction < 0.0)
    fail("static friction " + numberText(staticFriction) + ": expected a finite coefficient >= 0");
  if (!std::isfinite(kineticFriction) || kineticFriction < 0.0)
    fail("kinetic friction " + numberText(kineticFriction) + ": expected a finite coefficient >= 0");
  if (kineticFriction > staticFriction)
    fail("kinetic friction " + numberText(kineticFriction) + " exceeds static friction " + numberText(staticFriction) +
         ": expected kinetic <= static");
}

}  // namespace deformable_flsm
