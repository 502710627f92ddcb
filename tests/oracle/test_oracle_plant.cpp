// The oracle as the plant of a closed loop (oracle_plant.hpp): stepped through pamc's Plant it is the
// oracle's batch record sample for sample, and the paper's PI tracks Table 2's triangle on it - the
// experiments run unchanged on a plant that shares no code with pamc's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "control/controller.hpp"
#include "io/model_file.hpp"
#include "model/model.hpp"
#include "oracle_plant.hpp"
#include "sim/experiments.hpp"
#include "sim/lockstep.hpp"

using namespace pamc;

namespace {

oracle::Case secondPlant() {
  const auto cases = oracle::loadCases(std::string(PAMC_ORACLE_SOURCE_DIR) + "/closed_loop_plant.json");
  EXPECT_EQ(cases.size(), 1u);
  return cases.at(0);
}

}  // namespace

TEST(OraclePlant, SteppedThroughThePlantItIsTheOraclesRecord) {
  const oracle::Case c = secondPlant();
  const auto u = oracle::makeSignal(c.validate.input, c.validate.duration, 1e-3, c.validate.seed);
  std::vector<double> load(u.size(), 0.0);
  for (size_t k = u.size() / 2; k < u.size(); ++k) load[k] = 40.0;  // a payload on half way
  const auto batch = oracle::simulate(c.core, c.effects, u, &load, oracle::OracleDynamics::options(c, 1e-3));
  plant::Plant p(oracle::oraclePlant(c));
  const sim::Record stepped = sim::runOpenLoopSamples(p, u, &load);
  ASSERT_EQ(stepped.y.size(), batch.y.size());
  for (size_t k = 0; k < u.size(); k += 97) {
    EXPECT_EQ(stepped.y[k], batch.y[k]) << k;
    EXPECT_EQ(stepped.y_true[k], batch.y_clean[k]) << k;
  }
  // The payload is felt: the compliance moves the position.
  const std::vector<double> none(u.size(), 0.0);
  const auto unloaded = oracle::simulate(c.core, c.effects, u, &none, oracle::OracleDynamics::options(c, 1e-3));
  EXPECT_GT(std::fabs(batch.y_clean.back() - unloaded.y_clean.back()), 0.2);
}

TEST(OraclePlant, ThePapersPiTracksTheTriangleOnIt) {
  const plant::PlantConfig plant = oracle::oraclePlant(secondPlant());
  const model::Model m;  // the paper's model: only where the run starts from
  const control::ControllerConfig cc = sim::controllerFor(control::ControllerConfig{}, m, plant);
  control::InverseStatic inv;
  inv.build(m, cc.u_min, cc.u_max, plant.Ts);
  const sim::TrackingCase triangle = sim::table2Cases(sim::SineStart::Centre).at(0);
  ASSERT_NE(triangle.tag.find("triangle"), std::string::npos);
  const sim::Record r = sim::runController(control::Kind::PI, cc, inv, plant, triangle.run);
  const auto s = sim::tracking(r, sim::scoredFrom(r, triangle.run));
  EXPECT_LT(s.rmse, 0.5) << "PI on the oracle's muscle, triangle 0.2..30 mm";
  EXPECT_GT(s.rmse, 0.01);  // a real plant, with noise and lags: never the setpoint itself
}

// At 50 Hz, as a rig node runs: this plant sampled every 20 ms, the commands two cycles on the bus, the loop
// started from a vented muscle (-5 V) with a second's pre-roll, PI and MBC on the triangle with `model` (a
// file in tests/data/models), scored from the start. Returns {PI, MBC} RMSE [mm].
static std::pair<double, double> fiftyHertzFromVented(const std::string& model) {
  constexpr double kTs = 0.02;
  plant::PlantConfig pc = oracle::oraclePlant(secondPlant());
  pc.Ts = kTs;
  control::ControllerConfig cfg;
  cfg.Ts = kTs;
  cfg.u_min = pc.u_min;
  cfg.u_max = pc.u_max;
  cfg.model = io::readModelFile(std::string(PAMC_ORACLE_SOURCE_DIR) + "/../data/models/" + model);
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::triangle(0.05, 0.2, 30.0);
  run.duration_s = 40.0;
  run.preroll_s = 1.0;
  double rmse[2] = {0.0, 0.0};
  for (int i = 0; i < 2; ++i) {
    auto c = control::makeController(i == 0 ? control::Kind::PI : control::Kind::Mbc, cfg);
    plant::Plant p(pc);
    const sim::Record r = sim::runClosedLoop(*c, p, run, -5.0);
    double se = 0.0;
    for (size_t k = 0; k < r.t.size(); ++k) se += (r.yd[k] - r.y[k]) * (r.yd[k] - r.y[k]);
    rmse[i] = std::sqrt(se / static_cast<double>(r.t.size()));
  }
  std::printf("50 Hz on the oracle's plant with %s: PI %.4f mm, MBC %.4f mm\n", model.c_str(), rmse[0], rmse[1]);
  return {rmse[0], rmse[1]};
}

// With the final model of this plant's diagnose ladder (pneumatic_balance, tools/mbc_table.py --oracle-plant).
// The MBC's 50 Hz rules were written on the physics plant (docs/CONTROL.md, "At 50 Hz"); here they meet a
// plant they have not seen: the MBC tracks the triangle better than the PI (0.084 against 0.229 mm). This
// does not pin those rules: without them the MBC tracked this plant at 0.106 mm (0.114 with them, before
// the MBC started inside its model's range).
TEST(OraclePlant, AtFiftyHertzTheMbcWithTheLaddersModelTracksBetterThanThePi) {
  const auto [pi, mbc] = fiftyHertzFromVented("oracle_pneumatic_balance.json");
  EXPECT_LT(mbc, pi);
}

// The loop of a user with a rig (tools/vcan_model_loop.sh) on this plant: the model diagnose learns from the
// paper's u0 as this plant answers it (`pamc_oracle_experiments --only table1`, then `pamc diagnose
// ident_u0.csv --validate ident_u1.csv`: saturation, validated 0.133 mm; committed as
// oracle_u0_diagnosed.json), identified on [-2.7, 3.1] V and 1.7-28 mm, the triangle reaching below and
// above it. Bound, chosen before the run: better than the PI (0.128 against 0.229 mm; 0.134 before the MBC
// started inside its model's range - this plant's PI does not swing from the vented start, and the test does
// not pin that rule).
TEST(OraclePlant, AtFiftyHertzTheMbcWithTheModelOfU0TracksBetterThanThePi) {
  const auto [pi, mbc] = fiftyHertzFromVented("oracle_u0_diagnosed.json");
  EXPECT_LT(mbc, pi);
}
