/// @file contact.h
/// Geometry of the colliders (signed distance, outward normal, bounds, motion) and the contact
/// response of one particle sphere: the stateless kernels the solver's contact pass is built of.
#pragma once

#include "deformable_flsm/core/collider.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cstddef>
#include <map>
#include <string>
#include <vector>

namespace deformable_flsm {

/// Signed distance from a point to a shape's surface (m, negative inside) and the outward unit
/// normal there, in the collider's own frame. Exact for the half-space, box, sphere, capsule and
/// cylinder; a mesh is read from shape.distanceField (see MeshDistanceField for its accuracy).
/// @param[in]  shape   a valid shape; a mesh needs its distanceField
/// @param[in]  p       3 by 1 point in the collider frame (m)
/// @param[out] normal  3 by 1 outward unit normal (collider frame): the gradient of the distance;
///                     where it is not unique (centre of a sphere, axis of a capsule or
///                     cylinder, centre plane of a box) one of the nearest surface directions
/// @throws std::invalid_argument for a mesh shape without its distance field.
double shapeDistance(const ColliderShape& shape, const Eigen::Vector3d& p, Eigen::Vector3d& normal);

/// shapeDistance() of a point given in the simulation frame, for the collider at `pose`.
/// @param[in]  pose    collider frame in the simulation frame
/// @param[in]  x       3 by 1 point (m, simulation frame)
/// @param[out] normal  3 by 1 outward unit normal (simulation frame)
double colliderDistance(const ColliderShape& shape, const Eigen::Isometry3d& pose, const Eigen::Vector3d& x,
                        Eigen::Vector3d& normal);

/// Axis-aligned bounds of the shape in the simulation frame, for the collider at `pose`.
/// @return false for an unbounded shape (the half-space); lo, hi are then left alone.
bool colliderBounds(const ColliderShape& shape, const Eigen::Isometry3d& pose, Eigen::Vector3d& lo,
                    Eigen::Vector3d& hi);

/// Whether any point of the box [lo, hi] comes within `margin` of the collider (a cheap test:
/// it may say true for a box that is farther away, never false for one that is closer).
bool boxNearCollider(const ColliderShape& shape, const Eigen::Isometry3d& pose, const Eigen::Vector3d& lo,
                     const Eigen::Vector3d& hi, double margin);

/// The pose of a collider `t` seconds after `pose`, moving with constant linear velocity v of its
/// origin and angular velocity omega (both in the simulation frame):
///   p(t) = p + v t,  R(t) = exp(t [omega]x) R.
Eigen::Isometry3d advancePose(const Eigen::Isometry3d& pose, const Eigen::Vector3d& linearVelocity,
                              const Eigen::Vector3d& angularVelocity, double t);

/// How much of a contact's slip friction stops in one sub-step: Coulomb friction with a
/// continuous transition from static to kinetic.
///
/// Stopping the slip would take `needed` (a tangential velocity change, or impulse); the contact's
/// normal change over the sub-step is `normal` (velocity or impulse alike, N below). Up to
/// mu_s N friction stops all of it (static friction: the contact sticks); beyond that it gives
///   max(mu_k N, mu_s N - (mu_s - mu_k) (needed - mu_s N)),
/// falling linearly from mu_s N at the breakaway to the kinetic mu_k N once the slip beyond the
/// breakaway reaches N, the normal change of the sub-step (a Stribeck-like curve whose velocity
/// scale is that normal change).
/// Why not Coulomb's step from mu_s N to mu_k N: in a velocity-level step the slip left after
/// friction then jumps from 0 to (mu_s - mu_k) N as `needed` crosses mu_s N. A particle held at
/// the edge of its friction cone (a pile pressing it aslant onto the floor) that touches a
/// particle of another object alternates between the two branches, the object-contact solve
/// handing the pair's common slip back and forth, and their velocity flips every sub-step
/// forever. With the transition the slip left, needed - friction, is continuous and grows
/// from 0 at the breakaway (with slope 1 + mu_s - mu_k), so the pair's map has no jump to
/// alternate across (docs/method.md says what this does not guarantee). A contact that really slides, by more than
/// N per sub-step beyond the breakaway (on an incline, N = g cos(theta) h: from its first
/// sub-steps on), gets the kinetic mu_k N of Coulomb's law unchanged.
/// @param[in] needed  >= 0, what stopping the slip takes
/// @param[in] normal  >= 0, the normal change (same units)
/// @param[in] staticFriction   mu_s >= 0
/// @param[in] kineticFriction  mu_k in [0, mu_s]
/// @return the friction's magnitude, in [0, needed]
inline double frictionTaken(double needed, double normal, double staticFriction, double kineticFriction) {
  const double held = staticFriction * normal;
  if (needed <= held) return needed;
  return std::max(kineticFriction * normal, held - (staticFriction - kineticFriction) * (needed - held));
}

/// Velocity change of one particle in contact over a sub-step (velocity-level response with
/// Coulomb friction).
///
/// The particle is a sphere whose predicted end-of-sub-step position x* = x + h v lies
/// `depth` = phi(x*) - r < 0 inside the collider. Its start position x lay `startDepth` =
/// phi(x) - r from the collider's surface as it was at the start of the sub-step. The normal
/// change dv_n = (min(startDepth, 0) - depth) / h (none when that is negative) removes the
/// penetration the sub-step's own relative motion made: a particle that came from outside ends
/// on the surface (its end position x + h (v + dv) touches it), one that was already inside
/// (a collider set or teleported onto it, a reset into it, another collider's correction)
/// goes no deeper. Penetration that was there before the sub-step becomes no velocity: a
/// collider at rest does no work, and the velocity -startDepth / h (the penetration over one
/// sub-step, tens of m/s for a centimetre) is not handed to the particle. Turning it into
/// velocity was unstable where colliders overlap: pushed out of one into another, the particle
/// gets back every sub-step the distance it was moved over h, and its speed grows
/// geometrically. The solver moves such a particle out by position only (Solver::contactPass()).
/// For a particle already inside, dv_n is moreover at most its approach along the end normal,
/// max(0, -(v - v_c).n): an inelastic contact only stops motion into the surface. The signed
/// distance of a convex shape is convex, so phi(x) - phi(x*) >= -h (v - v_c).n: the depths
/// differ by more than the approach, by as much as the level sets curve over the path. Deep
/// inside a large collider they curve most (near a sphere's centre: a particle passing it ends
/// "shallower" on the far side while moving away from its new surface point), and "no deeper"
/// there threw the particle on along its motion, every sub-step it passed, faster each time.
/// Then the tangential part of the velocity relative to the collider's surface,
/// v_t = (I - n n^T)(v + dv_n n - v_c), is removed when that needs no more than mu_s dv_n (static
/// friction: the particle sticks), else reduced along -v_t by frictionTaken(|v_t|, dv_n, mu_s,
/// mu_k): kinetic friction mu_k dv_n once it slides, reached continuously from the breakaway. The
/// impulse m dv is what the collider receives, with the opposite sign.
/// @param[in] depth             phi(x*) - r (m), < 0
/// @param[in] startDepth        phi(x) - r (m) at the start of the sub-step, the collider at its
///                              pose then; >= 0 for a particle that came from outside
/// @param[in] normal            3 by 1 outward unit normal at x*
/// @param[in] velocity          3 by 1 particle velocity v (m/s)
/// @param[in] colliderVelocity  3 by 1 velocity of the collider's material at x*, v_lin + omega x (x* - o)
/// @param[in] h                 sub-step (s)
/// @param[in] staticFriction    mu_s >= 0
/// @param[in] kineticFriction   mu_k in [0, mu_s]
/// @return 3 by 1 velocity change dv (m/s)
inline Eigen::Vector3d contactVelocityChange(double depth, double startDepth, const Eigen::Vector3d& normal,
                                             const Eigen::Vector3d& velocity,
                                             const Eigen::Vector3d& colliderVelocity, double h,
                                             double staticFriction, double kineticFriction) {
  double dvn = std::max(0.0, std::min(startDepth, 0.0) - depth) / h;
  // inside since before the sub-step: stop at most the approach (see above)
  const double approach = -(velocity - colliderVelocity).dot(normal);
  if (startDepth < 0.0) dvn = std::min(dvn, std::max(0.0, approach));
  Eigen::Vector3d dv = dvn * normal;
  const Eigen::Vector3d rel = velocity + dv - colliderVelocity;
  const Eigen::Vector3d tangential = rel - rel.dot(normal) * normal;
  const double slip = tangential.norm();
  if (slip > 0.0) dv -= (frictionTaken(slip, dvn, staticFriction, kineticFriction) / slip) * tangential;
  return dv;
}

/// Moves points out of the colliders: a point closer than `margin` to a collider's surface (or
/// inside it) is moved along the normal to the distance `margin`. For the render vertices, which
/// interpolate the particles and may dip below a surface the particles stand on.
/// @param[in,out] points     #V by 3 points (m, simulation frame)
/// @param[in]     colliders  the colliders at their current poses (Solver::colliders()); a mesh
///                           collider without its distanceField gets a temporary one (slow)
/// @param[in]     margin     distance to keep from the surfaces (m), >= 0
/// @return the number of points moved
std::size_t projectOutOfColliders(std::vector<Eigen::Vector3d>& points,
                                  const std::map<std::string, Collider>& colliders, double margin);

}  // namespace deformable_flsm
