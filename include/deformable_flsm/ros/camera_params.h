/// @file camera_params.h
/// ~cameras from the parameter server: a list of dictionaries, each a depth camera
/// (runtime/camera_spec.h), every field checked.
#pragma once

#include "deformable_flsm/runtime/camera_spec.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <vector>

namespace deformable_flsm {

/// Parses ~cameras: each entry has `name` and `frame`, optionally `position` and `look_at` (m, in
/// ~frame_id: the node publishes `frame` there), `width`, `height` (pixels;
/// 640 x 480), `horizontal_fov` (rad; 60 degrees) or `fx` [, `fy`, `cx`, `cy`] (pixels), `near`,
/// `far` (m; 0.05, 10), `rate` (Hz; 15), `encoding` ('32FC1' or '16UC1'), `noise` ('none' or
/// 'kinect'), `seed`.
/// @throws ParamError naming the entry (index and name) and the key that is wrong.
std::vector<CameraSpec> parseCameraList(XmlRpc::XmlRpcValue& list);

}  // namespace deformable_flsm
