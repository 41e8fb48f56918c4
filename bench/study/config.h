/// @file config.h
/// The configuration of the speed/accuracy study (flsm_study): the resolutions and sub-steps of
/// its runs and of their reference runs, the peers' settings, the FEM oracle's and the
/// calibration's settings, and the names of the study's methods.
#pragma once

#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

/// Cantilever bar length (m); section L / 10.
constexpr double kBarLength = 1.0;

/// Resolutions of the accuracy runs and of the reference (finest) run. Multiples of the coarsest
/// resolution, so that the region radius is a whole number of cells at every one of them.
inline const std::vector<int> kBarResolutions = {20, 40, 60};
/// Resolutions of the column (physics only, no reference run).
inline const std::vector<int> kColumnResolutions = {20, 40};
constexpr int kBarReferenceResolution = 80;
inline const std::vector<int> kBunnyResolutions = {12, 24};
constexpr int kBunnyReferenceResolution = 36;
/// Bunny resolution of the stress scenarios.
constexpr int kStressResolution = 24;

/// Sub-steps per 1/60 s frame of FastLSM and Bullet, and of their reference runs.
inline const std::vector<int> kSubsteps = {1, 2, 4, 8};
constexpr int kReferenceSubsteps = 16;
/// FastLSM (and naive LSM) also run at twice the sub-steps, up to this many, while the last
/// count still capped alpha (the node names the sub-steps that would not): where its users
/// would run it for the asked material. The reference run takes the fewest powers of two from
/// kReferenceSubsteps on that leave alpha uncapped, up to kMaxReferenceSubsteps.
constexpr int kMaxFlsmSubsteps = 64;
/// FastLSM's implicit step: sub-steps per frame at every resolution of the explicit runs. No
/// bound on the modulus comes from its sub-step, so its users run it at the frame rate; two
/// sub-steps show what halving its numerical damping buys.
inline const std::vector<int> kImplicitSubsteps = {1, 2};
/// Resolutions of the implicit step's cantilever: kBarResolutions and the explicit step's
/// reference resolution, where the implicit step at the frame rate costs about what the explicit
/// one pays at 60 cells, at the accurate end of the chart where Bullet's deformable body stands.
inline const std::vector<int> kImplicitBarResolutions = {20, 40, 60, 80};
/// Stress table: Young's moduli (Pa) of the implicit step's runs beside the study's bunny
/// (kBunnyYoungsModulus), from a soft material to a stiff rubber, which the explicit step at one
/// sub-step could only simulate with alpha capped.
inline const std::vector<double> kImplicitStressModuli = {3e4, 1e6, 1e7};
constexpr int kMaxReferenceSubsteps = 128;
/// Naive LSM: the region sums cost O(w^3) per particle; the study runs it where w <= this.
constexpr int kNaiveMaxHalfWidth = 2;
/// Mass-spring: sub-steps are multiples of the fewest that are stable, s_min = the smallest
/// power of two with h omega_max <= kMassSpringStepMargin (symplectic Euler is stable below 2).
constexpr double kMassSpringStepMargin = 1.5;
inline const std::vector<int> kMassSpringSubstepFactors = {1, 2};
constexpr int kMassSpringReferenceFactor = 4;
/// Legacy Bullet: position iterations per sub-step; pose matching kMT per kBulletPoseMatchingStep
/// (Bullet's soft-body demos use kMT = 0.05 at 60 Hz); the softest kLST the calibration tries.
constexpr int kBulletIterations = 4;
constexpr double kBulletPoseMatching = 0.05;
constexpr double kBulletPoseMatchingStep = 1.0 / 60.0;
constexpr double kBulletMinStiffness = 1e-6;
/// Legacy Bullet's volume conservation pulls with this fraction of the material's bulk modulus:
/// its pressure is an explicit force, and the full bulk modulus blows the bunny up within three
/// frames at 1/60 s (a tenth of it within seven); users turn kVC down until the body is stable.
constexpr double kBulletVolumeFraction = 0.005;
/// Legacy Bullet's calibration runs at this many sub-steps (its cost per run is highest).
constexpr int kBulletCalibrationSubsteps = 4;
/// Bullet's deformable body (implicit): sub-steps per frame at each resolution of the bar runs
/// (index as kBarResolutions; none at the finer ones: ~10 s per simulated second at 60 cells). Its users run it at the frame rate; a
/// few sub-steps show what shorter steps buy. No reference run: its cost at the reference
/// resolution is beyond the study's budget, and physics is the reference that counts. It runs
/// the bar scenarios only: on the bunny its conjugate gradients cost ~10 s per simulated second at
/// resolution 12, beyond the study's budget for the ear drag and the stress scenarios.
inline const std::vector<std::vector<int>> kBulletFemSubsteps = {{1, 2, 4}, {1}};
/// FEM oracle: the bar's voxels at this resolution, each cell split into kFemSubdivision^3
/// linear hexahedra (8 elements across the section); and a coarser one (4 across) to show how
/// far the reference is from converged (trilinear elements are stiff in bending).
constexpr int kFemResolution = 40;
constexpr int kFemSubdivision = 2;
constexpr int kFemCheckResolution = 20;

/// Calibration setting: the bar at this resolution, FastLSM at the reference sub-steps, where
/// alpha is below its cap and the bar has the modulus it is given.
constexpr int kCalibrationResolution = 40;
constexpr int kCalibrationSubsteps = kReferenceSubsteps;
/// Runs whose first repetition took less CPU time than this (s) are repeated (--repeats):
/// cheap runs are the ones that other processes on the machine disturb most.
constexpr double kRepeatBelowSeconds = 2.0;
/// Trajectory samples of the ear drag: every this many frames (10 Hz).
constexpr int kSampleEvery = 6;

/// Every method of the study, in the order of its files and tables. "fastlsm-nu0" runs in the
/// stress table only.
inline const std::vector<std::string> kAllMethods = {"fastlsm",     "fastlsm-implicit", "fastlsm-nu0", "naive-lsm",
                                                     "mass-spring", "bullet",           "bullet-fem"};

}  // namespace study
}  // namespace deformable_flsm
