#include "deformable_flsm/ros/camera_params.h"

#include "entry_reader.h"

#include <cmath>
#include <limits>
#include <set>
#include <string>

namespace deformable_flsm {

namespace {

const std::vector<std::string> kFields = {"name",  "frame", "position", "look_at", "width",
                                          "height", "horizontal_fov", "fx", "fy", "cx", "cy",
                                          "near",  "far",   "rate",  "encoding", "noise", "seed"};
constexpr double kDefaultFov = 60.0 * 3.14159265358979323846 / 180.0;

CameraSpec parseEntry(XmlRpc::XmlRpcValue& entry, int index) {
  EntryReader r(entry, "~cameras", index, kFields);
  if (entry.getType() != XmlRpc::XmlRpcValue::TypeStruct)
    r.fail("it is " + describe(entry) + ": each camera is a dictionary (name, frame, width, ...)");
  CameraSpec c;
  c.name = r.string("name", "");
  r.setId(c.name);
  r.checkFields();
  if (!r.has("name")) r.fail("name is missing: each camera needs one (its topics are ~<name>/...)");
  if (!r.has("frame")) r.fail("frame is missing: give the tf frame of the camera's optical frame");
  c.frame = r.string("frame", "");
  if (r.has("position") != r.has("look_at"))
    r.fail("position and look_at go together: give both (the node places the camera's frame) or "
           "neither (another node publishes it on tf)");
  if (r.has("position")) {
    const Eigen::Vector3d eye = r.numbers("position", 3, Eigen::Vector3d::Zero());
    const Eigen::Vector3d at = r.numbers("look_at", 3, Eigen::Vector3d::Zero());
    if ((at - eye).norm() < 1e-9) r.fail("look_at is where the camera is: it must look somewhere else");
    c.placed = true;
    c.pose = opticalLookAt(eye, at);
  }
  CameraIntrinsics& k = c.intrinsics;
  k.width = r.integer("width", k.width, 1, CameraSpec::kMaxPixels);
  k.height = r.integer("height", k.height, 1, CameraSpec::kMaxPixels);
  if (r.has("horizontal_fov") && r.has("fx"))
    r.fail("horizontal_fov and fx are both set: give one (the field of view, or fx, fy, cx, cy)");
  if (!r.has("fx") && (r.has("fy") || r.has("cx") || r.has("cy")))
    r.fail("fy, cx or cy without fx: give fx too, or horizontal_fov alone");
  const double fov = r.number("horizontal_fov", kDefaultFov);
  if (!(fov > 0.0 && fov < 3.1))
    r.fail("horizontal_fov is " + std::to_string(fov) + ": it must be an angle in (0, 3.1) rad");
  k.fx = r.number("fx", 0.5 * k.width / std::tan(0.5 * fov));
  k.fy = r.number("fy", k.fx);
  k.cx = r.number("cx", 0.5 * (k.width - 1));
  k.cy = r.number("cy", 0.5 * (k.height - 1));
  k.near = r.number("near", k.near);
  k.far = r.number("far", k.far);
  c.rate = r.number("rate", c.rate);
  const std::string encoding = r.string("encoding", toString(c.encoding));
  if (encoding == "32FC1")
    c.encoding = CameraSpec::DepthEncoding::Float32Metres;
  else if (encoding == "16UC1")
    c.encoding = CameraSpec::DepthEncoding::UInt16Millimetres;
  else
    r.fail("encoding is '" + encoding + "': it must be '32FC1' (metres) or '16UC1' (millimetres)");
  const std::string noise = r.string("noise", "none");
  if (noise == "none")
    c.noise = CameraSpec::Noise::None;
  else if (noise == "kinect")
    c.noise = CameraSpec::Noise::Kinect;
  else
    r.fail("noise is '" + noise + "': it must be 'none' or 'kinect'");
  c.seed = static_cast<std::uint32_t>(r.integer("seed", 0, 0, std::numeric_limits<int>::max()));
  validateCamera(c, "~cameras entry " + std::to_string(index) + " ('" + c.name + "')");
  return c;
}

}  // namespace

std::vector<CameraSpec> parseCameraList(XmlRpc::XmlRpcValue& list) {
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray)
    throw ParamError("~cameras is " + describe(list) + ": it must be a list of cameras (dictionaries)");
  std::vector<CameraSpec> out;
  std::set<std::string> names;
  for (int i = 0; i < list.size(); ++i) {
    out.push_back(parseEntry(list[i], i));
    if (!names.insert(out.back().name).second)
      throw ParamError("~cameras entry " + std::to_string(i) + " ('" + out.back().name +
                       "'): name is taken by an earlier camera: each needs its own");
  }
  return out;
}

}  // namespace deformable_flsm
