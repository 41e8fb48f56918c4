/// @file test_object_params.cpp
/// Tests of ros/object_params.h and the scene of several objects (runtime/scene.h buildWorld()):
/// ~objects entries take the node's parameters as defaults and override them key by key; every
/// bad entry is refused naming the entry and the key; the objects are built where their poses
/// put them, share the colliders, and objects that start inside each other stop the start-up
/// naming both.
#include "deformable_flsm/ros/object_params.h"
#include "deformable_flsm/runtime/scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

namespace deformable_flsm {
namespace {

XmlRpc::XmlRpcValue numbers(std::initializer_list<double> values) {
  XmlRpc::XmlRpcValue v;
  v.setSize(static_cast<int>(values.size()));
  int k = 0;
  for (double x : values) v[k++] = x;
  return v;
}

XmlRpc::XmlRpcValue entry(const std::string& name) {
  XmlRpc::XmlRpcValue e;
  e["name"] = name;
  return e;
}

XmlRpc::XmlRpcValue list(std::initializer_list<XmlRpc::XmlRpcValue> entries) {
  XmlRpc::XmlRpcValue v;
  v.setSize(static_cast<int>(entries.size()));
  int k = 0;
  for (const XmlRpc::XmlRpcValue& e : entries) v[k++] = e;
  return v;
}

/// The message of the ParamError that parsing `entries` throws ("" if none).
std::string parseError(XmlRpc::XmlRpcValue entries, const NodeParams& defaults = NodeParams()) {
  try {
    parseObjectList(entries, defaults);
  } catch (const ParamError& e) {
    return e.what();
  }
  return "";
}

bool mentions(const std::string& text, const std::string& what) {
  return text.find(what) != std::string::npos;
}

TEST(ObjectParams, AnEntryOnItsOwnHasTheKeysAndChecksOfTheListAndNamesItsLabel) {
  // ~add_object's parameter: one entry, read as an entry of ~objects is
  XmlRpc::XmlRpcValue e = entry("late");
  e["resolution"] = 5;
  e["pose"] = numbers({0.1, 0.2, 0.3});
  const ObjectSpec spec = parseObjectEntry(e, NodeParams(), "parameter '/flsm_node/new'");
  EXPECT_EQ(spec.name, "late");
  EXPECT_EQ(spec.params.objectFrameId, "late");
  EXPECT_EQ(spec.params.resolution, 5);
  EXPECT_TRUE(spec.pose.translation().isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));
  e["colour"] = std::string("red");
  try {
    parseObjectEntry(e, NodeParams(), "parameter '/flsm_node/new'");
    FAIL() << "an unknown key was accepted";
  } catch (const ParamError& error) {
    const std::string what = error.what();
    EXPECT_TRUE(mentions(what, "parameter '/flsm_node/new' ('late')")) << what;
    EXPECT_TRUE(mentions(what, "unknown key 'colour'")) << what;
  }
}

TEST(ObjectParams, AnEntryOverridesTheNodesParametersKeyByKey) {
  NodeParams defaults;
  defaults.spacing = 0.02;
  defaults.regionHalfWidth = 3;
  defaults.solver.damping = 0.2;
  XmlRpc::XmlRpcValue a = entry("soft");
  a["youngs_modulus"] = 5000.0;
  a["resolution"] = 8;
  a["region_radius"] = 0.05;
  a["pose"] = numbers({1.0, 2.0, 3.0, 0.0, 0.0, M_PI / 2});
  a["mesh_scale"] = 0.05;
  XmlRpc::XmlRpcValue b = entry("plain");
  b["pose"] = numbers({0.0, 0.0, 0.5});
  XmlRpc::XmlRpcValue entries = list({a, b});
  const std::vector<ObjectSpec> objects = parseObjectList(entries, defaults);
  ASSERT_EQ(objects.size(), 2u);

  const ObjectSpec& soft = objects[0];
  EXPECT_EQ(soft.name, "soft");
  EXPECT_EQ(soft.params.objectFrameId, "soft");
  EXPECT_DOUBLE_EQ(soft.params.youngsModulus, 5000.0);
  EXPECT_DOUBLE_EQ(soft.params.solver.youngsModulus, 5000.0);  // applyMaterial()
  EXPECT_DOUBLE_EQ(soft.params.meshScale, 0.05);
  // the lattice from the entry's resolution: the node's spacing no longer applies
  EXPECT_EQ(soft.params.resolution, 8);
  EXPECT_EQ(soft.params.spacing, 0.0);
  // the regions from the entry's radius: the node's half-width no longer applies
  EXPECT_DOUBLE_EQ(soft.params.regionRadius, 0.05);
  EXPECT_EQ(soft.params.regionHalfWidth, 0);
  // what the entry does not give is the node's
  EXPECT_DOUBLE_EQ(soft.params.solver.damping, 0.2);
  EXPECT_EQ(soft.params.mesh, defaults.mesh);
  // pose: yaw a quarter turn maps x to y, then the translation
  const Eigen::Vector3d moved = soft.pose * Eigen::Vector3d(1.0, 0.0, 0.0);
  EXPECT_NEAR((moved - Eigen::Vector3d(1.0, 3.0, 3.0)).norm(), 0.0, 1e-12);

  const ObjectSpec& plain = objects[1];
  EXPECT_DOUBLE_EQ(plain.params.spacing, 0.02);
  EXPECT_EQ(plain.params.regionHalfWidth, 3);
  EXPECT_DOUBLE_EQ(plain.params.youngsModulus, defaults.youngsModulus);
  EXPECT_TRUE(plain.pose.linear().isIdentity(0.0));
  EXPECT_DOUBLE_EQ(plain.pose.translation().z(), 0.5);
}

TEST(ObjectParams, BadEntriesAreRefusedNamingTheEntryAndTheKey) {
  // not a list, or an empty one
  EXPECT_TRUE(mentions(parseError(XmlRpc::XmlRpcValue(std::string("bunny"))), "~objects is"));
  XmlRpc::XmlRpcValue empty;
  empty.setSize(0);
  EXPECT_TRUE(mentions(parseError(empty), "non-empty list"));
  // no name, a bad name, a duplicate, the simulation frame's name
  XmlRpc::XmlRpcValue nameless;
  nameless["mesh_scale"] = 0.1;
  EXPECT_TRUE(mentions(parseError(list({nameless})), "entry 0: it has no name"));
  EXPECT_TRUE(mentions(parseError(list({entry("a/b")})), "name 'a/b' must be a letter"));
  EXPECT_TRUE(mentions(parseError(list({entry("2nd")})), "name '2nd' must be a letter"));
  EXPECT_TRUE(mentions(parseError(list({entry("cube"), entry("cube")})),
                       "entry 1 ('cube'): name 'cube' is used by an earlier entry"));
  EXPECT_TRUE(mentions(parseError(list({entry("world")})), "is ~frame_id"));
  // an unknown key, a wrong type, a bad pose
  XmlRpc::XmlRpcValue typo = entry("cube");
  typo["youngs_modulos"] = 1e4;
  EXPECT_TRUE(mentions(parseError(list({typo})), "entry 0 ('cube'): unknown key 'youngs_modulos'"));
  XmlRpc::XmlRpcValue wrongType = entry("cube");
  wrongType["resolution"] = 8.5;
  EXPECT_TRUE(mentions(parseError(list({wrongType})), "resolution is 8.5"));
  XmlRpc::XmlRpcValue badPose = entry("cube");
  badPose["pose"] = numbers({1.0, 2.0});
  EXPECT_TRUE(mentions(parseError(list({badPose})), "pose is [1, 2]: it must be"));
  XmlRpc::XmlRpcValue nanPose = entry("cube");
  nanPose["pose"] = numbers({1.0, 2.0, std::nan("")});
  EXPECT_TRUE(mentions(parseError(list({nanPose})), "entry 0 ('cube'): pose is [1, 2, nan]"));
  // out of range, said with the entry's key (no "~": it is not the node's parameter)
  XmlRpc::XmlRpcValue soft = entry("cube");
  soft["youngs_modulus"] = -5.0;
  const std::string negative = parseError(list({soft}));
  EXPECT_TRUE(mentions(negative, "entry 0 ('cube'): youngs_modulus is -5")) << negative;
  XmlRpc::XmlRpcValue both = entry("cube");
  both["spacing"] = 0.01;
  both["resolution"] = 8;
  EXPECT_TRUE(mentions(parseError(list({both})), "spacing (0.01) and resolution (8) are both set"));
  XmlRpc::XmlRpcValue material = entry("cube");
  material["material"] = std::string("rubber");
  EXPECT_TRUE(mentions(parseError(list({material})), "material is 'rubber'"));
}

TEST(ObjectParams, SingleObjectIsNamedAfterTheObjectFrame) {
  NodeParams p;
  p.objectFrameId = "sponge";
  const ObjectSpec one = singleObject(p);
  EXPECT_EQ(one.name, "sponge");
  EXPECT_TRUE(one.pose.isApprox(Eigen::Isometry3d::Identity()));
}

/// Two coarse bunnies side by side, `apart` metres between their mesh origins along x.
std::vector<ObjectSpec> twoBunnies(double apart) {
  NodeParams defaults;
  defaults.resolution = 6;
  XmlRpc::XmlRpcValue a = entry("left");
  XmlRpc::XmlRpcValue b = entry("right");
  b["pose"] = numbers({apart, 0.0, 0.0});
  XmlRpc::XmlRpcValue entries = list({a, b});
  return parseObjectList(entries, defaults);
}

TEST(BuildWorld, ObjectsArePlacedByTheirPosesAndShareTheColliders) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyMeshPath)) << "install glmark2-data (a test dependency)";
  NodeParams node;
  const WorldScene scene = buildWorld(node, twoBunnies(1.0), loadMeshParam);
  ASSERT_EQ(scene.world->objectCount(), 2u);
  ASSERT_EQ(scene.objects.size(), 2u);
  EXPECT_EQ(scene.objects[0].name, "left");
  EXPECT_EQ(scene.objects[1].name, "right");
  const Lattice& left = *scene.objects[0].lattice;
  const Lattice& right = *scene.objects[1].lattice;
  // the same mesh and resolution: the same lattice, moved by the pose (up to the voxel grid,
  // which is anchored to each mesh's bounding box: exact)
  ASSERT_EQ(left.size(), right.size());
  EXPECT_NEAR((right.restMin() - left.restMin() - Eigen::Vector3d(1.0, 0.0, 0.0)).norm(), 0.0, 1e-9);
  // the ground below the lowest object, in both solvers
  for (const std::string& name : scene.world->objectNames())
    EXPECT_EQ(scene.world->object(name)->colliders().count("ground"), 1u) << name;
  EXPECT_EQ(scene.objects[0].info.colliders, 1u);
  EXPECT_FALSE(scene.objects[0].info.stepMeasured);
}

TEST(BuildWorld, ObjectsThatStartInsideEachOtherStopTheStartNamingBoth) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyMeshPath)) << "install glmark2-data (a test dependency)";
  NodeParams node;
  std::string message;
  try {
    buildWorld(node, twoBunnies(0.05), loadMeshParam);  // 5 cm apart: the 33 cm bunnies overlap
  } catch (const ParamError& e) {
    message = e.what();
  }
  EXPECT_TRUE(mentions(message, "left")) << message;
  EXPECT_TRUE(mentions(message, "right")) << message;
  EXPECT_TRUE(mentions(message, "pose")) << message;
}

}  // namespace
}  // namespace deformable_flsm
