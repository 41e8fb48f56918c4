/// @file test_collider_params.cpp
/// Tests of ros/collider_params.h, ros/collider_command_validator.h and
/// ros/collider_messages.h: ~colliders entries parsed or refused naming entry and field, the
/// ground below the object, ~collider commands checked and converted to the simulation frame,
/// markers and wrenches in the colliders' frames, a robot link's elements summed in its frame.
#include "deformable_flsm/ros/collider_command_validator.h"
#include "deformable_flsm/ros/collider_messages.h"
#include "deformable_flsm/ros/collider_params.h"
#include "deformable_flsm/ros/param_loader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace deformable_flsm {
namespace {

XmlRpc::XmlRpcValue list3(double a, double b, double c) {
  XmlRpc::XmlRpcValue v;
  v[0] = a;
  v[1] = b;
  v[2] = c;
  return v;
}

XmlRpc::XmlRpcValue boxEntry(const std::string& id) {
  XmlRpc::XmlRpcValue e;
  e["id"] = id;
  e["type"] = std::string("box");
  e["size"] = list3(0.02, 0.04, 0.1);
  return e;
}

/// The message of the ParamError that parsing `entries` throws ("" if none).
std::string parseError(XmlRpc::XmlRpcValue entries) {
  try {
    parseColliderList(entries, "world");
  } catch (const ParamError& e) {
    return e.what();
  }
  return "";
}

void expectMentions(const std::string& message, std::initializer_list<const char*> words) {
  EXPECT_FALSE(message.empty()) << "no error";
  for (const char* w : words) EXPECT_NE(message.find(w), std::string::npos) << message;
}

TEST(ColliderParams, ParsesEveryShapeWithItsPoseAndFriction) {
  XmlRpc::XmlRpcValue list;
  list[0] = boxEntry("left_finger");
  list[0]["frame_id"] = std::string("gripper");
  list[0]["position"] = list3(0.1, 0.0, 0.2);
  XmlRpc::XmlRpcValue q;
  q[0] = 0.0;
  q[1] = 0.0;
  q[2] = 2.0;  // not normalised: 180 degrees about z once normalised
  q[3] = 0.0;
  list[0]["orientation"] = q;
  list[0]["static_friction"] = 1.0;
  list[0]["kinetic_friction"] = 0.8;
  list[1]["id"] = std::string("ball");
  list[1]["type"] = std::string("sphere");
  list[1]["radius"] = 0.01;
  list[1]["frame_id"] = std::string("world");  // the simulation frame: fixed
  list[2]["id"] = std::string("rod");
  list[2]["type"] = std::string("capsule");
  list[2]["radius"] = 1;  // an integer is a number too
  list[2]["length"] = 0.08;
  list[3]["id"] = std::string("wall");
  list[3]["type"] = std::string("plane");
  list[4]["id"] = std::string("post");
  list[4]["type"] = std::string("cylinder");
  list[4]["radius"] = 0.02;
  list[4]["length"] = 0.3;

  const std::vector<ColliderSpec> specs = parseColliderList(list, "world");
  ASSERT_EQ(specs.size(), 5u);
  EXPECT_EQ(specs[0].id, "left_finger");
  EXPECT_EQ(specs[0].followFrame, "gripper");
  EXPECT_EQ(specs[0].collider.shape.type, ColliderType::Box);
  EXPECT_TRUE(specs[0].collider.shape.halfExtents.isApprox(Eigen::Vector3d(0.01, 0.02, 0.05)));
  EXPECT_TRUE(specs[0].collider.pose.translation().isApprox(Eigen::Vector3d(0.1, 0.0, 0.2)));
  EXPECT_TRUE((specs[0].collider.pose.linear() * Eigen::Vector3d::UnitX())
                  .isApprox(-Eigen::Vector3d::UnitX(), 1e-12));
  EXPECT_EQ(specs[0].collider.staticFriction, 1.0);
  EXPECT_EQ(specs[0].collider.kineticFriction, 0.8);
  EXPECT_EQ(specs[1].followFrame, "");
  EXPECT_EQ(specs[1].collider.shape.radius, 0.01);
  EXPECT_EQ(specs[2].collider.shape.radius, 1.0);
  EXPECT_DOUBLE_EQ(specs[2].collider.shape.halfLength, 0.04);
  EXPECT_EQ(specs[3].collider.shape.type, ColliderType::HalfSpace);
  EXPECT_EQ(specs[4].collider.shape.type, ColliderType::Cylinder);
  EXPECT_EQ(specs[4].collider.shape.radius, 0.02);
  EXPECT_DOUBLE_EQ(specs[4].collider.shape.halfLength, 0.15) << "length is the full length";
}

TEST(ColliderParams, LoadsAMeshColliderWithItsDistanceField) {
  XmlRpc::XmlRpcValue list;
  list[0]["id"] = std::string("bunny");
  list[0]["type"] = std::string("mesh");
  list[0]["mesh"] = std::string(NodeParams::kDefaultMesh);
  list[0]["mesh_scale"] = 0.05;
  const std::vector<ColliderSpec> specs = parseColliderList(list, "world");
  ASSERT_EQ(specs.size(), 1u);
  ASSERT_TRUE(specs[0].collider.shape.mesh);
  EXPECT_GT(specs[0].collider.shape.mesh->triangles.size(), 1000u);
  EXPECT_TRUE(specs[0].collider.shape.distanceField);
}

TEST(ColliderParams, BadEntriesNameTheEntryAndTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  XmlRpc::XmlRpcValue notAList = std::string("box");
  expectMentions(parseError(notAList), {"~colliders", "a list"});

  XmlRpc::XmlRpcValue l;
  l[0] = boxEntry("a");
  l[0]["type"] = std::string("cone");
  expectMentions(parseError(l), {"entry 0", "'a'", "'cone'", "plane, box, sphere, capsule, cylinder or mesh"});

  l[0] = boxEntry("a");
  l[1] = boxEntry("b");
  l[1]["size"] = list3(0.1, -0.1, 0.1);
  expectMentions(parseError(l), {"entry 1", "'b'", "size", "> 0"});

  l[1] = boxEntry("b");
  l[1]["size"] = list3(0.1, nan, 0.1);
  expectMentions(parseError(l), {"entry 1", "size", "finite"});

  l[1] = boxEntry("a");
  expectMentions(parseError(l), {"entry 1", "'a'", "earlier entry"});

  l[1] = boxEntry("b");
  XmlRpc::XmlRpcValue zero;
  for (int k = 0; k < 4; ++k) zero[k] = 0.0;
  l[1]["orientation"] = zero;
  expectMentions(parseError(l), {"'b'", "orientation", "zero"});

  l[1] = boxEntry("b");
  l[1]["raduis"] = 0.1;
  expectMentions(parseError(l), {"'b'", "unknown field 'raduis'"});

  l[1] = XmlRpc::XmlRpcValue();
  l[1]["id"] = std::string("s");
  l[1]["type"] = std::string("sphere");
  expectMentions(parseError(l), {"'s'", "needs radius"});
  l[1]["radius"] = -0.01;
  expectMentions(parseError(l), {"'s'", "radius", "> 0"});
  l[1]["radius"] = 0.01;
  l[1]["static_friction"] = 0.2;
  expectMentions(parseError(l), {"'s'", "kinetic_friction <= static_friction"});

  l[1] = XmlRpc::XmlRpcValue();
  l[1]["id"] = std::string("m");
  l[1]["type"] = std::string("mesh");
  l[1]["mesh"] = std::string("/nonexistent/flsm/collider.obj");
  expectMentions(parseError(l), {"'m'", "/nonexistent/flsm/collider.obj"});

  l[1] = boxEntry("");
  expectMentions(parseError(l), {"entry 1", "printable characters"});
}

TEST(ColliderParams, GroundLiesClearanceBelowTheLowestRestPointAgainstGravity) {
  Voxelization v;
  v.spacing = 0.01;
  v.dims = Eigen::Vector3i(2, 2, 2);
  v.closed = true;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) {
        v.cells.emplace_back(i, j, k);
        v.fillFraction.push_back(1.0);
      }
  const Lattice lattice(v, 1000.0, 1);
  TriMesh mesh;
  mesh.vertices = {lattice.restMin() - Eigen::Vector3d::Constant(0.003), lattice.restMax()};
  const double r = 0.005, clearance = 0.1;

  // Gravity along -z: the lowest point is the mesh's (3 mm below the lowest particle, less
  // than the contact radius 5 mm: the particles' spheres reach lower).
  Collider g = groundCollider(lattice, mesh, Eigen::Vector3d(0, 0, -9.81), r, clearance);
  EXPECT_EQ(g.shape.type, ColliderType::HalfSpace);
  EXPECT_TRUE(g.pose.linear().col(2).isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(g.pose.translation().z(), lattice.restMin().z() - r - clearance, 1e-12);

  // Gravity along +x: the ground is a wall at the high-x side, its normal along -x.
  g = groundCollider(lattice, mesh, Eigen::Vector3d(9.81, 0, 0), r, 0.0);
  EXPECT_TRUE(g.pose.linear().col(2).isApprox(-Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(g.pose.translation().x(), lattice.restMax().x() + r, 1e-12);
}

// --- ~collider commands -------------------------------------------------------------------------

ColliderCommandValidator validator() {
  // One known frame, "table": 1 m up and turned 90 degrees about z.
  return ColliderCommandValidator(
      "world", [](const std::string& frame, const ros::Time&, Eigen::Isometry3d& T,
                  std::string& why) {
        if (frame != "table") {
          why = "unknown";
          return false;
        }
        T = Eigen::Translation3d(0, 0, 1) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
        return true;
      });
}

ColliderCommand boxCommand() {
  ColliderCommand m;
  m.action = ColliderCommand::ADD;
  m.id = "probe";
  m.type = "box";
  m.pose.orientation.w = 1.0;
  m.size.x = m.size.y = m.size.z = 0.1;
  m.static_friction = 0.6;
  m.kinetic_friction = 0.5;
  return m;
}

std::string refusal(const ColliderCommand& m) {
  CommandBody out;
  Rejection why;
  return validator().check(m, out, why) ? std::string() : why.reason;
}

TEST(ColliderCommandValidator, AddMoveAndRemoveInTheSimulationFrame) {
  ColliderCommandValidator v = validator();
  CommandBody out;
  Rejection why;
  ColliderCommand m = boxCommand();
  m.header.frame_id = "table";
  m.pose.position.x = 0.5;
  ASSERT_TRUE(v.check(m, out, why)) << why.detail;
  const auto& add = std::get<SetColliderCommand>(out);
  EXPECT_TRUE(add.followFrame.empty());
  EXPECT_TRUE(add.collider.pose.translation().isApprox(Eigen::Vector3d(0, 0.5, 1), 1e-12));
  EXPECT_TRUE(add.collider.shape.halfExtents.isApprox(Eigen::Vector3d::Constant(0.05)));
  {
    ColliderCommand c = boxCommand();
    c.type = "cylinder";
    c.length = 0.2;
    c.radius = 0.03;
    CommandBody cylinder;
    ASSERT_TRUE(v.check(c, cylinder, why)) << why.detail;
    const ColliderShape& shape = std::get<SetColliderCommand>(cylinder).collider.shape;
    EXPECT_EQ(shape.type, ColliderType::Cylinder);
    EXPECT_EQ(shape.halfLength, 0.1);
    EXPECT_EQ(shape.radius, 0.03);
  }

  // Following a frame: the pose is the offset in it, no lookup now.
  m.header.frame_id = "nowhere";
  m.follow_frame = "gripper";
  ASSERT_TRUE(v.check(m, out, why)) << why.detail;
  EXPECT_EQ(std::get<SetColliderCommand>(out).followFrame, "gripper");
  EXPECT_TRUE(std::get<SetColliderCommand>(out).collider.pose.translation().isApprox(
      Eigen::Vector3d(0.5, 0, 0)));

  m = boxCommand();
  m.action = ColliderCommand::MOVE;
  m.header.frame_id = "table";
  m.velocity.linear.x = 0.2;
  m.velocity.angular.x = 1.0;
  ASSERT_TRUE(v.check(m, out, why)) << why.detail;
  const auto& move = std::get<MoveColliderCommand>(out);
  EXPECT_TRUE(move.pose.translation().isApprox(Eigen::Vector3d(0, 0, 1)));
  EXPECT_TRUE(move.linearVelocity.isApprox(Eigen::Vector3d(0, 0.2, 0), 1e-12));
  EXPECT_TRUE(move.angularVelocity.isApprox(Eigen::Vector3d(0, 1.0, 0), 1e-12));

  m.action = ColliderCommand::REMOVE;
  m.pose.position.x = std::nan("");  // not looked at
  ASSERT_TRUE(v.check(m, out, why));
  EXPECT_EQ(std::get<RemoveColliderCommand>(out).id, "probe");
}

TEST(ColliderCommandValidator, RefusesWithAReason) {
  const double nan = std::nan("");
  ColliderCommand m = boxCommand();
  m.action = 9;
  EXPECT_EQ(refusal(m), "bad_action");
  m = boxCommand();
  m.id = std::string(65, 'x');
  EXPECT_EQ(refusal(m), "bad_id");
  m = boxCommand();
  m.id = "tab\there";
  EXPECT_EQ(refusal(m), "bad_id");
  m = boxCommand();
  m.type = "cone";
  EXPECT_EQ(refusal(m), "bad_type");
  m = boxCommand();
  m.pose.position.y = nan;
  EXPECT_EQ(refusal(m), "non_finite");
  m = boxCommand();
  m.radius = nan;  // unused by a box, still refused: NaN anywhere means a broken sender
  EXPECT_EQ(refusal(m), "non_finite");
  m = boxCommand();
  m.pose.orientation.w = 0.0;
  EXPECT_EQ(refusal(m), "bad_orientation");
  m = boxCommand();
  m.size.z = 0.0;
  EXPECT_EQ(refusal(m), "bad_size");
  m = boxCommand();
  m.type = "capsule";
  m.radius = 0.01;
  m.length = -0.1;
  EXPECT_EQ(refusal(m), "bad_size");
  m.type = "cylinder";  // a cylinder needs a length > 0 (a capsule of length 0 is a sphere)
  m.length = 0.0;
  EXPECT_EQ(refusal(m), "bad_size");
  m.length = 0.1;
  m.radius = 0.0;
  EXPECT_EQ(refusal(m), "bad_size");
  m = boxCommand();
  m.static_friction = 0.1;
  EXPECT_EQ(refusal(m), "bad_friction");
  m = boxCommand();
  m.type = "mesh";
  m.mesh = "/nonexistent/flsm.obj";
  EXPECT_EQ(refusal(m), "bad_mesh");
  m = boxCommand();
  m.header.frame_id = "nowhere";
  EXPECT_EQ(refusal(m), "unknown_frame");
  m = boxCommand();
  m.action = ColliderCommand::MOVE;
  m.velocity.angular.z = nan;
  EXPECT_EQ(refusal(m), "non_finite");
}

// --- messages -----------------------------------------------------------------------------------

TEST(ColliderMessages, WrenchesAreInTheCollidersFrames) {
  std::map<std::string, Collider> colliders;
  Collider turned;
  turned.shape.type = ColliderType::Sphere;
  turned.shape.radius = 0.1;
  turned.pose = Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  colliders["turned"] = turned;
  colliders["ground"] = Collider();
  std::map<std::string, ContactWrench> wrenches;
  wrenches["turned"].force = Eigen::Vector3d(1, 0, 0);  // along the collider's -y
  wrenches["turned"].torque = Eigen::Vector3d(0, 0, 2);
  wrenches["turned"].contacts = 7;
  ContactWrenches msg;
  fillContactWrenches(colliders, wrenches, ros::Time(5.0), msg);
  ASSERT_EQ(msg.ids.size(), 2u);
  EXPECT_EQ(msg.ids[1], "turned");
  EXPECT_EQ(msg.wrenches[1].header.frame_id, colliderFrameId("turned"));
  EXPECT_NEAR(msg.wrenches[1].wrench.force.x, 0.0, 1e-12);
  EXPECT_NEAR(msg.wrenches[1].wrench.force.y, -1.0, 1e-12);
  EXPECT_NEAR(msg.wrenches[1].wrench.torque.z, 2.0, 1e-12);
  EXPECT_EQ(msg.contacts[1], 7u);
  EXPECT_EQ(msg.contacts[0], 0u);  // no wrench known: zero
  EXPECT_EQ(msg.wrenches[0].wrench.force.z, 0.0);

  std::vector<geometry_msgs::TransformStamped> tfs;
  colliderTransforms(colliders, "world", ros::Time(5.0), tfs);
  ASSERT_EQ(tfs.size(), 2u);
  EXPECT_EQ(tfs[1].child_frame_id, "flsm_collider/turned");
  EXPECT_EQ(tfs[1].transform.translation.z, 3.0);
}

// A drag's entry is what the object exerts on the hand: minus the drag's force and torque on the
// object, in the simulation frame, with the particles it holds.
TEST(ColliderMessages, DragsAppearAsWhatTheObjectExertsOnTheHand) {
  std::vector<ObjectSnapshot> objects(2);
  objects[0].name = "object";
  objects[1].name = "cube";
  DragView d;
  d.id = "lift";
  d.force = Eigen::Vector3d(0, 0, 2.5);  // the drag holds 2.5 N of weight up
  d.torque = Eigen::Vector3d(0.1, 0, 0);
  d.particles = 20;
  objects[1].drags.push_back(d);
  ContactWrenches msg;
  appendDragWrenches(objects, "world", ros::Time(3.0), msg);
  ASSERT_EQ(msg.ids.size(), 1u);
  EXPECT_EQ(msg.ids[0], dragWrenchId("cube", "lift"));
  EXPECT_EQ(msg.ids[0], "drag/cube/lift");
  EXPECT_EQ(msg.wrenches[0].header.frame_id, "world");
  EXPECT_EQ(msg.wrenches[0].wrench.force.z, -2.5);  // the object pulls the hand down
  EXPECT_EQ(msg.wrenches[0].wrench.torque.x, -0.1);
  EXPECT_EQ(msg.contacts[0], 20u);
}

TEST(ColliderMessages, GroupedCollidersAreSummedInTheirBodyFrame) {
  // A link at (1, 0, 0) turned 90 degrees about z, with two collision elements: A at (0.1, 0, 0)
  // in the link frame, pushed down by 1 N; B at (0, 0.2, 0), pushed along the world's x by 1 N
  // with 0.5 N m about z. About the link origin, in the world: F = (1, 0, -1),
  // tau = (0, 0.1, 0) x (0, 0, -1) + (0, 0, 0.5) + (-0.2, 0, 0) x (1, 0, 0) = (-0.1, 0, 0.5);
  // in the link frame (R^T: world x -> link -y, world y -> link x): F = (0, -1, -1),
  // tau = (0, 0.1, 0.5).
  const Eigen::Isometry3d link(Eigen::Translation3d(1, 0, 0) *
                               Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const Eigen::Isometry3d offsetA(Eigen::Translation3d(0.1, 0, 0)), offsetB(Eigen::Translation3d(0, 0.2, 0));
  std::map<std::string, Collider> colliders;
  colliders["robot/hand/0"].pose = link * offsetA;
  colliders["robot/hand/1"].pose = link * offsetB;
  colliders["wall"] = Collider();
  std::map<std::string, ContactWrench> wrenches;
  wrenches["robot/hand/0"].force = Eigen::Vector3d(0, 0, -1);
  wrenches["robot/hand/0"].contacts = 3;
  wrenches["robot/hand/1"].force = Eigen::Vector3d(1, 0, 0);
  wrenches["robot/hand/1"].torque = Eigen::Vector3d(0, 0, 0.5);
  wrenches["robot/hand/1"].contacts = 4;
  std::map<std::string, WrenchGroup> groups;
  groups["robot/hand/0"] = WrenchGroup{"robot/hand", "hand", offsetA};
  groups["robot/hand/1"] = WrenchGroup{"robot/hand", "hand", offsetB};
  groups["robot/elbow/0"] = WrenchGroup{"robot/elbow", "elbow", Eigen::Isometry3d::Identity()};
  ContactWrenches msg;
  fillContactWrenches(colliders, wrenches, groups, ros::Time(2.0), msg);
  ASSERT_EQ(msg.ids.size(), 2u) << "the wall, then one entry for the hand; none for the absent elbow";
  EXPECT_EQ(msg.ids[0], "wall");
  EXPECT_EQ(msg.ids[1], "robot/hand");
  const geometry_msgs::WrenchStamped& w = msg.wrenches[1];
  EXPECT_EQ(w.header.frame_id, "hand");
  EXPECT_NEAR(w.wrench.force.x, 0.0, 1e-12);
  EXPECT_NEAR(w.wrench.force.y, -1.0, 1e-12);
  EXPECT_NEAR(w.wrench.force.z, -1.0, 1e-12);
  EXPECT_NEAR(w.wrench.torque.x, 0.0, 1e-12);
  EXPECT_NEAR(w.wrench.torque.y, 0.1, 1e-12);
  EXPECT_NEAR(w.wrench.torque.z, 0.5, 1e-12);
  EXPECT_EQ(msg.contacts[1], 7u);
}

TEST(ColliderMessages, MarkersShowEveryShape) {
  using visualization_msgs::Marker;
  std::map<std::string, Collider> colliders;
  colliders["a_plane"] = Collider();
  Collider capsule;
  capsule.shape.type = ColliderType::Capsule;
  capsule.shape.radius = 0.01;
  capsule.shape.halfLength = 0.04;
  colliders["b_capsule"] = capsule;
  Collider mesh;
  mesh.shape.type = ColliderType::Mesh;
  auto tri = std::make_shared<TriMesh>();
  tri->vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri->triangles = {{0, 1, 2}};
  mesh.shape.mesh = tri;
  mesh.pose.translation() = Eigen::Vector3d(0, 0, 5);
  colliders["c_mesh"] = mesh;

  visualization_msgs::MarkerArray markers;
  fillColliderMarkers(colliders, "world", 2.0, ros::Time(1.0), markers);
  ASSERT_EQ(markers.markers.size(), 1u + 1u + 3u + 1u);
  EXPECT_EQ(markers.markers[0].action, Marker::DELETEALL);
  const Marker& plane = markers.markers[1];
  EXPECT_EQ(plane.type, Marker::CUBE);
  EXPECT_EQ(plane.scale.x, 2.0);
  // The slab's top face is the plane z = 0.
  EXPECT_NEAR(plane.pose.position.z + 0.5 * plane.scale.z, 0.0, 1e-12);
  EXPECT_EQ(markers.markers[2].type, Marker::CYLINDER);
  EXPECT_DOUBLE_EQ(markers.markers[2].scale.z, 0.08);
  EXPECT_EQ(markers.markers[3].type, Marker::SPHERE);
  EXPECT_DOUBLE_EQ(markers.markers[3].pose.position.z, -0.04);
  EXPECT_DOUBLE_EQ(markers.markers[4].pose.position.z, 0.04);
  const Marker& m = markers.markers[5];
  EXPECT_EQ(m.type, Marker::TRIANGLE_LIST);
  EXPECT_EQ(m.ns, "c_mesh");
  ASSERT_EQ(m.points.size(), 3u);
  EXPECT_EQ(m.points[1].x, 1.0);  // in the collider frame; the pose places it
  EXPECT_EQ(m.pose.position.z, 5.0);
}

}  // namespace
}  // namespace deformable_flsm
