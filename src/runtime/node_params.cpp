#include "deformable_flsm/runtime/node_params.h"

#include "deformable_flsm/core/resolution.h"

#include <cmath>
#include <sstream>

namespace deformable_flsm {

namespace {

std::string str(const Eigen::Vector3d& v) {
  std::ostringstream os;
  os << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return os.str();
}

}  // namespace

void NodeParams::validate() const {
  const std::string scalar = scalarProblem();
  if (!scalar.empty()) throw ParamError(scalar);
  checkPinned();
  checkColliders();
  checkFrictions();
  // The solver's own ranges (stiffness, damping, time step, ...); w is checked once known.
  SolverParams s = solver;
  s.youngsModulus = material == Material::Youngs ? youngsModulus : 0.0;
  s.regionHalfWidth = regionHalfWidth > 0 ? regionHalfWidth : s.regionHalfWidth;
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string("~") + e.what());
  }
}

std::string NodeParams::scalarProblem() const {
  std::ostringstream why;
  if (mesh.empty()) {
    why << "~mesh is empty: set it to a mesh file (e.g. " << kDefaultMesh
        << ") or a package:// URL";
  } else if (!std::isfinite(meshScale) || meshScale <= 0.0) {
    why << "~mesh_scale is " << meshScale
        << ": it must be a finite number > 0 (the factor from file units to metres)";
  } else if (!meshRpy.allFinite()) {
    why << "~mesh_rpy is " << str(meshRpy) << ": it must be three finite angles (rad)";
  } else if (frameId.empty()) {
    why << "~frame_id is empty: set it to the frame the object lives in (e.g. world)";
  } else if (objectFrameId.empty() || objectFrameId == frameId) {
    why << "~object_frame_id is '" << objectFrameId
        << "': it must be a non-empty frame name different from ~frame_id ('" << frameId << "')";
  } else if (!std::isfinite(spacing) || spacing < 0.0) {
    why << "~spacing is " << spacing << ": it must be a finite lattice spacing > 0 (m), or 0 "
        << "to use ~resolution or ~particle_budget";
  } else if (resolution < 0) {
    why << "~resolution is " << resolution
        << ": it must be a number of cells > 0, or 0 to use ~spacing or ~particle_budget";
  } else if (spacing > 0.0 && resolution > 0) {
    why << "~spacing (" << spacing << ") and ~resolution (" << resolution
        << ") are both set: set one of them to 0 (or remove it)";
  } else if (maxParticles < 1) {
    why << "~max_particles is " << maxParticles << ": it must be >= 1";
  } else if (spacing == 0.0 && resolution == 0 &&
             (particleBudget < 1 || particleBudget > maxParticles)) {
    why << "~particle_budget is " << particleBudget << ": it must be from 1 to ~max_particles ("
        << maxParticles << ")";
  } else if (!std::isfinite(regionRadius) || regionRadius < 0.0) {
    why << "~region_radius is " << regionRadius
        << ": it must be a finite radius > 0 (m), or 0 to use ~region_half_width";
  } else if (regionHalfWidth < 0) {
    why << "~region_half_width is " << regionHalfWidth
        << ": it must be a number of cells >= 1, or 0 to use ~region_radius";
  } else if (regionRadius > 0.0 && regionHalfWidth > 0) {
    why << "~region_radius (" << regionRadius << " m) and ~region_half_width ("
        << regionHalfWidth << " cells) are both set: keep one (region_radius is preferred: it "
        << "keeps the regions' size when the lattice changes)";
  } else if (!std::isfinite(publishRate) || publishRate <= 0.0 || publishRate > kMaxPublishRate) {
    why << "~publish_rate is " << publishRate << ": it must be a finite rate in (0, "
        << kMaxPublishRate << "] Hz";
  } else if (realTimeFactor == 0.0 && clock != Clock::Sim) {
    why << "~real_time_factor is 0 (as fast as the machine can) with ~clock " << toString(clock)
        << ": that needs ~clock sim, where the node serves the time it steps; with ~clock wall "
        << "give a factor in (0, " << kMaxRealTimeFactor << "]";
  } else if (!std::isfinite(realTimeFactor) || realTimeFactor < 0.0 ||
             realTimeFactor > kMaxRealTimeFactor) {
    why << "~real_time_factor is " << realTimeFactor << ": it must be in (0, "
        << kMaxRealTimeFactor << "] (simulated seconds per wall-clock second), or 0 with ~clock sim";
  } else if (material == Material::Youngs && (!std::isfinite(youngsModulus) || youngsModulus <= 0.0)) {
    why << "~youngs_modulus is " << youngsModulus << ": it must be a finite modulus > 0 (Pa) "
        << "with ~material youngs (a firm jelly is ~1e4, rubber ~1e6); to give alpha per "
        << "sub-step directly as ~stiffness instead, set ~material to classic";
  } else if (!std::isfinite(solver.contactRadius) || solver.contactRadius < 0.0) {
    why << "~contact_radius is " << solver.contactRadius
        << ": it must be a finite radius > 0 (m), or 0 for half the lattice spacing";
  } else if (!std::isfinite(groundClearance) || groundClearance < 0.0) {
    why << "~ground_clearance is " << groundClearance
        << ": it must be a finite gap >= 0 (m) between the object and the ground";
  } else if (renderTriangleBudget < 0) {
    why << "~render_triangle_budget is " << renderTriangleBudget
        << ": it must be a number of triangles >= 1, or 0 to render the mesh as loaded";
  }
  return why.str();
}

void NodeParams::checkPinned() const {
  for (std::size_t b = 0; b < pinned.size(); ++b) {
    const Box& box = pinned[b];
    if (!box.lo.allFinite() || !box.hi.allFinite() || (box.lo.array() > box.hi.array()).any()) {
      throw ParamError("~pinned box " + std::to_string(b) + " is [" + str(box.lo) + ", " +
                       str(box.hi) + "]: each box is [xmin, ymin, zmin, xmax, ymax, zmax] of "
                       "finite numbers (m) with min <= max");
    }
  }
}

void NodeParams::checkColliders() const {
  for (std::size_t c = 0; c < colliders.size(); ++c) {
    if (ground && colliders[c].id == ColliderLimits::kGroundId) {
      throw ParamError("~colliders entry " + std::to_string(c) + " ('ground'): the id 'ground' "
                       "is the ground's (~ground is true): rename the entry or set ~ground "
                       "to false");
    }
  }
  if (colliders.size() + (ground ? 1 : 0) > ColliderLimits::kMaxColliders) {
    throw ParamError("~colliders and ~ground make " +
                     std::to_string(colliders.size() + (ground ? 1 : 0)) +
                     " colliders: at most " + std::to_string(ColliderLimits::kMaxColliders));
  }
  const std::size_t all = colliders.size() + (ground ? 1 : 0) + robot.colliders.size();
  if (all > ColliderLimits::kMaxColliders) {
    throw ParamError("the robot's " + std::to_string(robot.colliders.size()) +
                     " collision elements with ~colliders and ~ground make " +
                     std::to_string(all) + " colliders: at most " +
                     std::to_string(ColliderLimits::kMaxColliders) +
                     "; leave links out with ~robot_links or ~robot_exclude_links");
  }
  for (const RobotCollider& r : robot.colliders) {
    for (const ColliderSpec& c : colliders) {
      if (c.id == r.spec.id)
        throw ParamError("~colliders entry '" + c.id + "': the id is the robot's collider of "
                         "link '" + r.link + "': rename the entry");
    }
  }
}

void NodeParams::checkFrictions() const {
  if (!std::isfinite(objectContact.kineticFriction) || objectContact.kineticFriction < 0.0 ||
      !std::isfinite(objectContact.staticFriction) ||
      objectContact.staticFriction < objectContact.kineticFriction) {
    throw ParamError("~object_static_friction " + std::to_string(objectContact.staticFriction) +
                     ", ~object_kinetic_friction " +
                     std::to_string(objectContact.kineticFriction) +
                     ": they must satisfy 0 <= kinetic <= static");
  }
  const RobotColliderOptions& ro = robot.options;
  if (!std::isfinite(ro.kineticFriction) || ro.kineticFriction < 0.0 ||
      !std::isfinite(ro.staticFriction) || ro.staticFriction < ro.kineticFriction) {
    throw ParamError("~robot_static_friction " + std::to_string(ro.staticFriction) +
                     ", ~robot_kinetic_friction " + std::to_string(ro.kineticFriction) +
                     ": they must satisfy 0 <= kinetic <= static");
  }
}

int NodeParams::resolveRegionHalfWidth(double latticeSpacing, int* askedCells) const {
  if (askedCells) *askedCells = 0;
  if (regionHalfWidth > 0) return regionHalfWidth;
  // Unset: with a modulus, the narrowest regions. Shape matching averages a deformation over a
  // region, so a dent narrower than a region meets less than the modulus (a punch 5 cells wide
  // carries 0.90, 0.71 and 0.39 of a linear FEM's force at w = 1, 2 and 4; docs/method.md);
  // wider regions are for a scene that is only pushed as a whole.
  if (regionRadius <= 0.0) return material == Material::Youngs ? 1 : SolverParams().regionHalfWidth;
  if (std::isfinite(latticeSpacing) && latticeSpacing > 0.0 &&
      std::round(regionRadius / latticeSpacing) > kMaxRegionHalfWidth) {
    // The same radius in metres is more cells on a finer lattice (a smaller object at the same
    // particle budget): take the largest regions the solver allows rather than refuse to start.
    if (askedCells) *askedCells = static_cast<int>(std::round(regionRadius / latticeSpacing));
    return kMaxRegionHalfWidth;
  }
  try {
    return regionHalfWidthForRadius(regionRadius, latticeSpacing);
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string("~") + e.what());
  }
}

const char* toString(NodeParams::Material material) {
  return material == NodeParams::Material::Youngs ? "youngs" : "classic";
}

bool parseMaterial(const std::string& name, NodeParams::Material& material) {
  if (name == "youngs") {
    material = NodeParams::Material::Youngs;
  } else if (name == "classic") {
    material = NodeParams::Material::Classic;
  } else {
    return false;
  }
  return true;
}

bool isTopicLevel(const std::string& name) {
  return !name.empty() && name.find_first_of(" /~") == std::string::npos;
}

const char* toString(NodeParams::Clock clock) {
  switch (clock) {
    case NodeParams::Clock::Wall: return "wall";
    case NodeParams::Clock::Sim: return "sim";
    case NodeParams::Clock::Follow: return "follow";
  }
  return "wall";
}

bool parseClock(const std::string& name, NodeParams::Clock& clock) {
  for (NodeParams::Clock c : {NodeParams::Clock::Wall, NodeParams::Clock::Sim, NodeParams::Clock::Follow}) {
    if (name == toString(c)) {
      clock = c;
      return true;
    }
  }
  return false;
}

}  // namespace deformable_flsm
