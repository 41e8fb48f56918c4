// deformable_flsm._core: the simulation for Python, built from the node's own parameters (the
// dictionary a YAML file of them loads to) by the node's own loader and scene builder, stepped
// with the GIL released. Positions and velocities are numpy views of the solver's arrays.
#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/ros/object_params.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/runtime/collider_spec.h"
#include "deformable_flsm/runtime/scene.h"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace py = pybind11;

namespace deformable_flsm {
namespace {

/// A Python value as the parameter server holds it (YAML's types): dict, list, bool, int,
/// float, str.
XmlRpc::XmlRpcValue toXmlRpc(const py::handle& value, const std::string& path) {
  if (py::isinstance<py::bool_>(value)) return XmlRpc::XmlRpcValue(value.cast<bool>());
  if (py::isinstance<py::int_>(value)) {
    const long long v = value.cast<long long>();
    if (v < INT32_MIN || v > INT32_MAX) throw ParamError(path + " is an integer beyond 32 bits");
    return XmlRpc::XmlRpcValue(static_cast<int>(v));
  }
  if (py::isinstance<py::float_>(value)) return XmlRpc::XmlRpcValue(value.cast<double>());
  if (py::isinstance<py::str>(value)) return XmlRpc::XmlRpcValue(value.cast<std::string>());
  if (py::isinstance<py::dict>(value)) {
    XmlRpc::XmlRpcValue out;
    out.begin();  // makes it a (so far empty) struct
    for (const auto& item : value.cast<py::dict>()) {
      const std::string key = py::str(item.first);
      out[key] = toXmlRpc(item.second, path + "/" + key);
    }
    return out;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    const py::sequence seq = value.cast<py::sequence>();
    XmlRpc::XmlRpcValue out;
    out.setSize(static_cast<int>(seq.size()));
    for (std::size_t k = 0; k < seq.size(); ++k)
      out[static_cast<int>(k)] = toXmlRpc(seq[k], path + "[" + std::to_string(k) + "]");
    return out;
  }
  throw ParamError(path + " is a " + std::string(py::str(value.get_type().attr("__name__"))) +
                   ": a parameter is a number, a string, true/false, a list or a dictionary");
}

Eigen::Isometry3d poseFrom(const Eigen::Vector3d& position, const Eigen::Vector4d& xyzw) {
  const double n = xyzw.norm();
  if (!position.allFinite() || !xyzw.allFinite() || std::abs(n - 1.0) > 1e-3)
    throw std::invalid_argument("a pose needs a finite position and a unit quaternion [x, y, z, w]");
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]).normalized().toRotationMatrix();
  pose.translation() = position;
  return pose;
}

/// One scene as the node builds it from its parameters: a World of its objects and colliders.
class Simulation {
 public:
  Simulation(const py::dict& params, const std::string& source) {
    const ParamLoader loader(toXmlRpc(params, source), source);
    params_ = loader.loadNodeParams();
    std::vector<ObjectSpec> objects = loader.loadObjects(params_);
    unknown_ = loader.unknownParams();
    scene_ = buildNodeScene(params_, objects, loadMeshParam, 0);
    for (const ColliderSpec& spec : params_.colliders)
      if (!spec.followFrame.empty()) followers_[spec.id] = spec;
  }

  World& world() { return *scene_.world; }

  /// the parameters nobody reads (misspelt?)
  const std::vector<std::string>& unknownParams() const { return unknown_; }
  std::vector<std::string> objectNames() const { return scene_.world->objectNames(); }

  /// object `name` ("" the first), its solver and what renders it
  const Solver& object(const std::string& name) const { return *scene_.world->object(sceneObject(name).name); }
  const SceneObject& sceneObject(const std::string& name) const {
    const std::string& wanted = name.empty() ? scene_.world->objectNames().front() : name;
    for (const SceneObject& o : scene_.objects)
      if (o.name == wanted) return o;
    throw py::key_error("no object '" + name + "'");
  }

  void step(int steps) {
    if (steps < 0) throw std::invalid_argument("steps must be >= 0");
    py::gil_scoped_release release;
    for (int k = 0; k < steps; ++k) scene_.world->step();
  }

  std::vector<std::string> colliderIds() const {
    std::vector<std::string> ids;
    const Solver& first = object("");
    for (const auto& entry : first.colliders()) ids.push_back(entry.first);
    for (const auto& entry : followers_)
      if (!first.colliders().count(entry.first)) ids.push_back(entry.first);
    return ids;
  }

  /// Sets collider `id`'s pose at the start of the next step and its velocity over that step.
  /// For a collider that follows a frame (`frame:` in its entry), the pose is the frame's and
  /// the entry's offset is applied; it joins the scene at its first pose, as in the node.
  void moveCollider(const std::string& id, const Eigen::Vector3d& position, const Eigen::Vector4d& xyzw,
                    const Eigen::Vector3d& linear, const Eigen::Vector3d& angular) {
    if (!linear.allFinite() || !angular.allFinite())
      throw std::invalid_argument("collider '" + id + "': velocities must be finite");
    Eigen::Isometry3d pose = poseFrom(position, xyzw);
    const auto follower = followers_.find(id);
    if (follower != followers_.end()) {
      const Eigen::Isometry3d& offset = follower->second.collider.pose;
      // the collider's origin moves with the frame: its velocity there, not at the frame's origin
      const Eigen::Vector3d atCollider = linear + angular.cross(pose.linear() * offset.translation());
      pose = pose * offset;
      if (!object("").colliders().count(id)) {
        Collider c = follower->second.collider;
        c.pose = pose;
        scene_.world->setCollider(id, c);
      }
      scene_.world->moveCollider(id, pose, atCollider, angular);
      return;
    }
    if (!scene_.world->moveCollider(id, pose, linear, angular))
      throw py::key_error("no collider '" + id + "'");
  }

  py::dict contactWrench(const std::string& id) const {
    const std::vector<std::string> ids = colliderIds();
    if (std::find(ids.begin(), ids.end(), id) == ids.end()) throw py::key_error("no collider '" + id + "'");
    const ContactWrench w = scene_.world->contactWrench(id);
    py::dict out;
    out["force"] = Eigen::Vector3d(w.force);
    out["torque"] = Eigen::Vector3d(w.torque);
    out["contacts"] = w.contacts;
    out["buried"] = w.buried;
    return out;
  }

  py::dict info(const std::string& name) const {
    const SceneObject& o = sceneObject(name);
    const Solver& s = object(name);
    py::dict out;
    out["particles"] = o.info.particles;
    out["spacing"] = o.info.spacing;
    out["region_half_width"] = o.info.regionHalfWidth;
    out["total_mass"] = o.info.totalMass;
    out["contact_radius"] = o.info.contactRadius;
    out["alpha"] = s.alpha();
    out["requested_alpha"] = o.info.requestedAlpha;
    out["stiffness_saturated"] = s.stiffnessSaturated();
    out["integrator"] = std::string(toString(s.params().integrator));
    out["substeps"] = s.params().substeps;
    out["integrator_choice"] = o.info.integratorChoice;
    out["pinned"] = o.info.pinned;
    out["ground_height"] = o.info.groundHeight;
    return out;
  }

  const NodeParams& params() const { return params_; }

 private:
  NodeParams params_;
  WorldScene scene_;
  std::vector<std::string> unknown_;
  std::map<std::string, ColliderSpec> followers_;
};

/// Material points of an object followed as the render mesh is (trilinear in the lattice, ghosts
/// near the surface): markers on the object, a tracked point cloud.
class Markers {
 public:
  Markers(const Solver& solver, const Eigen::Ref<const Eigen::MatrixXd>& rest) : solver_(solver) {
    if (rest.cols() != 3 || rest.rows() < 1 || !rest.allFinite())
      throw std::invalid_argument("markers: rest points must be a finite (K, 3) array");
    std::vector<Eigen::Vector3d> points(static_cast<std::size_t>(rest.rows()));
    for (Eigen::Index k = 0; k < rest.rows(); ++k) points[static_cast<std::size_t>(k)] = rest.row(k).transpose();
    embedding_ = std::make_unique<Embedding>(solver.lattice(), points);
  }
  /// (K, 3) where the points are now (m)
  py::array_t<double> positions() const {
    embedding_->deform(solver_.positions(), solver_.regionRotations(), scratch_);
    py::array_t<double> out({static_cast<py::ssize_t>(scratch_.size()), py::ssize_t{3}});
    auto w = out.mutable_unchecked<2>();
    for (std::size_t k = 0; k < scratch_.size(); ++k)
      for (int a = 0; a < 3; ++a) w(static_cast<py::ssize_t>(k), a) = scratch_[k][a];
    return out;
  }

 private:
  const Solver& solver_;
  std::unique_ptr<Embedding> embedding_;
  mutable std::vector<Eigen::Vector3d> scratch_;
};

/// A read-only (N, 3) view of a vector of Vector3d (three packed doubles each), alive as long as
/// `owner` is.
py::array_t<double> view(const std::vector<Eigen::Vector3d>& v, const py::object& owner) {
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "Vector3d is three packed doubles");
  py::array_t<double> a({static_cast<py::ssize_t>(v.size()), py::ssize_t{3}},
                        {static_cast<py::ssize_t>(sizeof(Eigen::Vector3d)), static_cast<py::ssize_t>(sizeof(double))},
                        v.empty() ? nullptr : v.front().data(), owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

}  // namespace
}  // namespace deformable_flsm

PYBIND11_MODULE(_core, m) {
  using namespace deformable_flsm;
  m.doc() = "FastLSM deformable objects (the ROS-free core of deformable_flsm), built from the "
            "node's parameters";
  py::register_exception<ParamError>(m, "ParamError", PyExc_ValueError);

  py::class_<Markers>(m, "Markers")
      .def("positions", &Markers::positions, "(K, 3) where the points are now (m), a copy");

  py::class_<Simulation>(m, "Simulation")
      .def(py::init<const py::dict&, const std::string&>(), py::arg("params"),
           py::arg("source") = "parameters",
           "Builds the scene the node would build from these private parameters (a dict as a "
           "YAML file of them loads). Raises ParamError naming the parameter to fix.")
      .def_property_readonly("unknown_params", &Simulation::unknownParams,
                             "names given that are not parameters of the node (misspelt?)")
      .def_property_readonly("objects", &Simulation::objectNames)
      .def_property_readonly("time", [](Simulation& s) { return s.world().time(); },
                             "simulated time (s)")
      .def_property_readonly("time_step", [](Simulation& s) { return s.world().timeStep(); })
      .def_property_readonly("substeps", [](Simulation& s) { return s.world().substeps(); })
      .def("step", &Simulation::step, py::arg("steps") = 1,
           "Advances `steps` time steps (the GIL released meanwhile).")
      .def("positions",
           [](py::object self, const std::string& name) {
             return view(self.cast<Simulation&>().object(name).positions(), self);
           },
           py::arg("name") = "", "(N, 3) particle positions (m), a read-only view valid until the next step")
      .def("velocities",
           [](py::object self, const std::string& name) {
             return view(self.cast<Simulation&>().object(name).velocities(), self);
           },
           py::arg("name") = "", "(N, 3) particle velocities (m/s), a read-only view")
      .def("rest_positions",
           [](py::object self, const std::string& name) {
             return view(self.cast<Simulation&>().object(name).lattice().restPositions(), self);
           },
           py::arg("name") = "", "(N, 3) rest positions (m), a read-only view")
      .def("pinned",
           [](Simulation& s, const std::string& name) {
             const Solver& o = s.object(name);
             py::array_t<bool> out(static_cast<py::ssize_t>(o.lattice().size()));
             auto w = out.mutable_unchecked<1>();
             for (std::uint32_t i = 0; i < o.lattice().size(); ++i) w(i) = o.isPinned(i);
             return out;
           },
           py::arg("name") = "")
      .def("markers",
           [](py::object self, const Eigen::Ref<const Eigen::MatrixXd>& rest, const std::string& name) {
             return Markers(self.cast<Simulation&>().object(name), rest);
           },
           py::arg("rest"), py::arg("name") = "", py::keep_alive<0, 1>(),
           "Points of the object given at rest ((K, 3), m, simulation frame) followed as the "
           "render mesh is: markers(rest).positions() is where they are now")
      .def("info", &Simulation::info, py::arg("name") = "",
           "the lattice, regions and material chosen for an object")
      .def_property_readonly("colliders", &Simulation::colliderIds)
      .def("move_collider", &Simulation::moveCollider, py::arg("id"), py::arg("position"),
           py::arg("orientation") = Eigen::Vector4d(0, 0, 0, 1),
           py::arg("linear_velocity") = Eigen::Vector3d::Zero(),
           py::arg("angular_velocity") = Eigen::Vector3d::Zero(),
           "Pose (orientation as [x, y, z, w]) at the start of the next step and velocity over it.")
      .def("contact_wrench", &Simulation::contactWrench, py::arg("id"),
           "force (N) and torque (N m) the objects exerted on collider `id` over the last step");
}
