/// @file collider.h
/// Rigid shapes the deformable object touches: a half-space (ground, wall), box, sphere,
/// capsule, cylinder, or a rigid triangle mesh. Each is static or kinematic: the caller gives its pose and
/// velocity for every step; the object never moves it (one-way coupling), and the solver reports
/// the force and torque the object exerts on it.
#pragma once

#include "deformable_flsm/core/mesh.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>

namespace deformable_flsm {

class MeshDistanceField;

enum class ColliderType {
  /// the solid z <= 0 of the collider frame (outward normal +z): ground or wall
  HalfSpace,
  /// |x| <= halfExtents component-wise, centred at the frame origin
  Box,
  /// |x| <= radius
  Sphere,
  /// points within radius of the segment from (0, 0, -halfLength) to (0, 0, +halfLength)
  Capsule,
  /// the capped cylinder x^2 + y^2 <= radius^2, |z| <= halfLength (flat ends, as a URDF
  /// <cylinder> of length 2 halfLength)
  Cylinder,
  /// the inside of a closed triangle mesh given in the collider frame
  Mesh,
};

/// Parses "plane" (or "half_space"), "box", "sphere", "capsule", "cylinder", "mesh".
/// @throws std::invalid_argument naming the accepted words otherwise.
ColliderType parseColliderType(const std::string& name);
/// "plane", "box", "sphere", "capsule", "cylinder" or "mesh".
const char* toString(ColliderType type);

/// Geometry in the collider's own frame (m).
struct ColliderShape {
  ColliderType type = ColliderType::HalfSpace;
  /// Box: half extents (m), each > 0
  Eigen::Vector3d halfExtents = Eigen::Vector3d::Zero();
  /// Sphere, Capsule, Cylinder: radius (m), > 0
  double radius = 0.0;
  /// Capsule: half the length of the axis segment along the frame's z axis (m), >= 0;
  /// Cylinder: half its length along the frame's z axis (m), > 0
  double halfLength = 0.0;
  /// Mesh: closed triangle mesh in the collider frame (non-empty)
  std::shared_ptr<const TriMesh> mesh;
  /// Mesh: its signed distance field (mesh_distance_field.h). Solver::setCollider() builds it
  /// when it is missing; give one to share it between colliders of the same mesh.
  std::shared_ptr<const MeshDistanceField> distanceField;

  /// @throws std::invalid_argument saying which field is wrong (NaN, negative, missing, empty
  ///         or open mesh).
  void validate() const;
};

/// A static or kinematic rigid collider.
struct Collider {
  ColliderShape shape;
  /// collider frame in the simulation frame
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  /// velocity of the frame origin (m/s, simulation frame)
  Eigen::Vector3d linearVelocity = Eigen::Vector3d::Zero();
  /// angular velocity (rad/s, simulation frame)
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();
  /// Coulomb friction: a contact sticks while |tangential| <= staticFriction * normal, else it
  /// slides with kineticFriction * normal opposing the slip. 0 <= kinetic <= static.
  double staticFriction = 0.6;
  double kineticFriction = 0.5;

  /// @throws std::invalid_argument saying which field is wrong.
  void validate() const;
};

/// What the object exerts on a collider, averaged over the last Solver::step().
struct ContactWrench {
  /// force on the collider (N, simulation frame)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  /// torque on the collider about its frame origin (N m, simulation frame)
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  /// particles in contact at the end of the last sub-step
  std::size_t contacts = 0;
  /// the most particles that began one of the step's sub-steps deeper than their radius inside
  /// the collider: it was placed, or moved in one jump, into the object rather than moved into
  /// it, so they are pushed out through its nearest face (a pad set into a surface sends the
  /// particles under its edges out sideways)
  std::size_t buried = 0;
};

/// One particle's push on a collider over the last step (Solver::recordContacts()).
struct ParticleContact {
  /// the particle's index in its object
  std::uint32_t particle = 0;
  /// where its sphere met the collider's surface at its last contact in the step (m, simulation
  /// frame)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  /// its force on the collider, the step's mean (N, simulation frame)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
};

/// A scene's colliders by id: kept once, by a World for all its objects (Solver::shareColliders())
/// or by a Solver alone.
using ColliderMap = std::map<std::string, Collider>;

}  // namespace deformable_flsm
