// The study's stress scenarios (bench/study/scenarios.h) with the implicit step (backward Euler
// and BDF2) at one sub-step of 1/30 s, from a soft to a stiff material: a drag 5 object sizes away, a collapse onto a plane and
// a scrambled start. Each must stay finite and come back to the rest shape and its volume, as the
// explicit step does at the study's modulus (test_scenarios.cpp), at moduli the explicit step
// cannot take in one sub-step.
#include "deformable_flsm/core/mesh.h"
#include "study/method.h"
#include "study/metrics.h"
#include "study/scenarios.h"
#include "study/setting.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

namespace study = deformable_flsm::study;
using deformable_flsm::Integrator;
using deformable_flsm::SolverKind;
using study::Scenario;

namespace {

const char* const kBunny = deformable_flsm::kBunnyMeshPath;
/// The coarsest bunny lattice of the study (552 particles, w = 1).
constexpr int kResolution = 12;

}  // namespace

class ImplicitStressScenario : public ::testing::TestWithParam<Scenario> {};

TEST_P(ImplicitStressScenario, StaysFiniteAndRecoversTheRestShapeUpTo10MPa) {
  ASSERT_TRUE(std::filesystem::exists(kBunny)) << kBunny << " missing: install glmark2-data (a test dependency)";
  const Scenario scenario = GetParam();
  const study::StudyObject bunny = study::makeBunny(kBunny, 0.1);
  const auto lattice = study::buildLattice(bunny, kResolution);
  for (auto scheme : {deformable_flsm::ImplicitScheme::BackwardEuler, deformable_flsm::ImplicitScheme::Bdf2}) {
    for (double E : {30e3, 10e6}) {
      study::Setting setting = study::scenarioSetting(scenario, bunny, kResolution, 1);
      ASSERT_DOUBLE_EQ(setting.frameStep, 1.0 / 30.0);
      setting.youngsModulus = E;
      deformable_flsm::SolverParams p = study::flsmParams(setting, lattice->regionHalfWidth(), SolverKind::Fast);
      p.integrator = Integrator::Implicit;
      p.implicitScheme = scheme;
      const std::string what = std::string(toString(scenario)) + ", " + toString(scheme) + ", E " + std::to_string(E);
      study::FlsmMethod method(lattice, p);
      const study::RunRecord rec = study::runScenario(scenario, bunny, *lattice, method, setting.frameStep, 0);
      // runScenario checks every frame: a non-finite coordinate or a particle 100 sizes away ends it.
      ASSERT_FALSE(rec.blewUp) << what << " at frame " << rec.blowUpFrame;
      EXPECT_TRUE(std::isfinite(rec.peakKineticEnergy));
      // the study's recovery criterion (1 % of the size) and the render mesh's volume within 1 %
      EXPECT_LT(rec.shapeError, study::kRecoveredTolerance) << what;
      EXPECT_TRUE(std::isfinite(rec.recoveredAfter)) << what;
      EXPECT_LT(std::abs(rec.finalVolumeChange), 0.01) << what;
      std::printf("  %s: recovered after %.1f s, error %.2g%% of the size, volume %+.2g%%, peak energy %.3g J\n",
                  what.c_str(), rec.recoveredAfter, 100 * rec.shapeError, 100 * rec.finalVolumeChange,
                  rec.peakKineticEnergy);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Study, ImplicitStressScenario,
                         ::testing::Values(Scenario::DragFar, Scenario::Plane, Scenario::Scrambled),
                         [](const ::testing::TestParamInfo<Scenario>& info) {
                           std::string name = study::toString(info.param);
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });
