/// @file collider_messages.h
/// Builds the messages that show the colliders: ~colliders (MarkerArray), ~contact_wrenches
/// (ContactWrenches) and the colliders' tf frames. Pure functions of their inputs: no master,
/// no publishing.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/world.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include <Eigen/Geometry>

#include <deformable_flsm/ContactWrenches.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <visualization_msgs/MarkerArray.h>

#include <map>
#include <string>
#include <vector>

namespace deformable_flsm {

/// The colliders as markers in `frameId`, one namespace per collider id: a plane as a square
/// slab `planeSize` wide and 1 % of it thick whose top face is the plane; a box as a CUBE; a
/// sphere as a SPHERE; a capsule as a CYLINDER (id 0) and two SPHEREs (ids 1, 2); a cylinder as a CYLINDER; a mesh as a
/// TRIANGLE_LIST whose points are in the collider frame and whose pose is the collider's.
/// The first marker is a DELETEALL, so that RViz forgets removed colliders.
/// @param[in]  colliders  by id, poses in the simulation frame (m)
/// @param[in]  frameId    header.frame_id (the simulation frame)
/// @param[in]  planeSize  edge of the square that shows a plane (m, > 0)
/// @param[in]  stamp      header.stamp
/// @param[out] markers    replaced
void fillColliderMarkers(const std::map<std::string, Collider>& colliders,
                         const std::string& frameId, double planeSize, const ros::Time& stamp,
                         visualization_msgs::MarkerArray& markers);

/// What the object exerts on each collider, each expressed in the collider's own frame
/// (colliderFrameId(id)): the simulation-frame force and torque (about the collider origin)
/// rotated by the inverse of the collider's orientation.
/// @param[in]  colliders  by id, poses in the simulation frame
/// @param[in]  wrenches   by id, simulation frame (an id missing here gets a zero wrench)
/// @param[in]  stamp      the stamp of every header
/// @param[out] out        replaced
void fillContactWrenches(const std::map<std::string, Collider>& colliders,
                         const std::map<std::string, ContactWrench>& wrenches,
                         const ros::Time& stamp, ContactWrenches& out);

/// The id of the entry of ~contact_wrenches for what object `from` exerts on object `on`.
std::string objectWrenchId(const std::string& from, const std::string& on);

/// Appends what each object exerted on each other it touched (World::objectWrenches()): id
/// objectWrenchId(from, on), the force on `on` and the torque about the simulation frame's
/// origin, both in the simulation frame (header.frame_id `simFrame`), and the particle pairs in
/// contact. Each touching pair appears twice, (a, b) and (b, a), with opposite wrenches.
void appendObjectWrenches(const std::vector<ObjectPairWrench>& pairs, const std::string& simFrame,
                          const ros::Time& stamp, ContactWrenches& out);

/// The id of the entry of ~contact_wrenches for what `object` exerts on its drag `drag`.
std::string dragWrenchId(const std::string& object, const std::string& drag);

/// Appends what each object exerted on each of its drags (the hand holding it) over the step:
/// id dragWrenchId(object, drag), minus the drag's force on the object and minus its torque about
/// the drag frame's origin, in the simulation frame (header.frame_id `simFrame`); the particles
/// the drag holds as its contacts. At rest a hard drag that lifts an object carries its weight.
void appendDragWrenches(const std::vector<ObjectSnapshot>& objects, const std::string& simFrame,
                        const ros::Time& stamp, ContactWrenches& out);

/// A collider reported together with others as one body (the collision elements of a robot
/// link): the body's id in ~contact_wrenches, its tf frame, and the collider's pose in it.
struct WrenchGroup {
  std::string id;
  std::string frame;
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
};

/// fillContactWrenches() with the colliders named in `groups` summed per body instead: one entry
/// per body (after the others, by body id) whose header.frame_id is the body's frame, with the
/// force and the torque about the body frame's origin expressed in it,
///   F_b = R_b^T sum F_c,  tau_b = R_b^T sum (tau_c + (o_c - o_b) x F_c),
/// where the body frame (R_b, o_b) = the collider's pose times offset^-1 (simulation frame), and
/// contacts summed. A body none of whose colliders is in `colliders` is left out.
void fillContactWrenches(const std::map<std::string, Collider>& colliders,
                         const std::map<std::string, ContactWrench>& wrenches,
                         const std::map<std::string, WrenchGroup>& groups, const ros::Time& stamp,
                         ContactWrenches& out);

/// One transform per collider, from `frameId` to colliderFrameId(id).
void colliderTransforms(const std::map<std::string, Collider>& colliders,
                        const std::string& frameId, const ros::Time& stamp,
                        std::vector<geometry_msgs::TransformStamped>& out);

}  // namespace deformable_flsm
