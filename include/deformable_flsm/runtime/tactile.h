/// @file tactile.h
/// A tactile sensor on a box collider's face (~tactile): a grid of taxels over the face, and per
/// taxel the normal pressure and the shear the object exerts there, from the particles' recorded
/// contact forces (Solver::recordContacts()). The pressures times the taxel area add up to the
/// normal force on the face, the shears to its tangential force. No ROS.
#pragma once

#include "deformable_flsm/core/collider.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace deformable_flsm {

struct TactileSpec {
  /// its images are under ~tactile/<name>/
  std::string name;
  /// the collider it covers (a box: ~colliders' id, or a robot link's "robot/<link>/<k>")
  std::string collider;
  /// the face: its outward normal is +/- the collider frame's axis `axis` (0 x, 1 y, 2 z)
  int axis = 2;
  int sign = 1;
  /// taxels along the face's v axis (rows) and u axis (columns), (u, v, outward normal)
  /// right-handed: for a + face u is the axis after `axis` (x -> y -> z -> x) and v the one after
  /// u, for a - face the two swapped (tactileColumnAxis(), tactileRowAxis())
  int rows = 16, cols = 16;

  static constexpr int kMaxTaxels = 1024;  ///< rows and columns at most
};

/// Parses "+x", "-x", "+y", "-y", "+z", "-z" into axis and sign; false otherwise.
bool parseFace(const std::string& face, int& axis, int& sign);
/// "+x" ... "-z".
std::string faceName(int axis, int sign);
/// The collider-frame axis a sensor's columns run along (u), and its rows (v).
int tactileColumnAxis(const TactileSpec& spec);
int tactileRowAxis(const TactileSpec& spec);

/// One frame of a tactile sensor, row-major rows x cols.
struct TactileImage {
  int rows = 0, cols = 0;
  /// m^2 of one taxel
  double taxelArea = 0.0;
  /// N/m^2: the normal pressure on each taxel (>= 0 where the object presses)
  std::vector<float> pressure;
  /// N/m^2: the shear along the face's u and v axes, two values a taxel
  std::vector<float> shear;
  /// N: what fell on the face in all (the normal force, positive into the face, and the shear
  /// along u and v), and what of the collider's recorded force fell elsewhere (the box's other
  /// half; simulation frame)
  double normalForce = 0.0;
  Eigen::Vector2d shearForce = Eigen::Vector2d::Zero();
  Eigen::Vector3d elsewhere = Eigen::Vector3d::Zero();
};

/// The image of sensor `spec` on box collider `box` (its pose now) from the collider's recorded
/// contacts: a contact belongs to the face when its point lies in the face's half of the box; it
/// goes to the taxel under it, one on a side face near the edge (an object pressed around the
/// pad's rim) to the edge's taxel: so the pressures add up to the whole push along the face's
/// normal.
/// @throws std::invalid_argument when `box` is not a box.
void tactileImage(const TactileSpec& spec, const Collider& box, const std::vector<ParticleContact>& contacts,
                  TactileImage& out);

}  // namespace deformable_flsm
