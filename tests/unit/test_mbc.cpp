// The model-based controller (Kind::Mbc, src/control/mbc.cpp): its feedforward through the commands in
// flight, its fallback to the PI outside the model's range, and a wrong model that must not cost a run.
// The plant is the physics plant of the experiments (src/physics), which shares no code with the model.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "control/controller.hpp"
#include "control/controller_parts.hpp"
#include "control/trajectory.hpp"
#include "diagnose/diagnose.hpp"
#include "ident/identify.hpp"
#include "io/model_file.hpp"
#include "model/held_rest.hpp"
#include "model/inverse_fold.hpp"
#include "plant/plant.hpp"
#include "sim/experiments.hpp"
#include "sim/lockstep.hpp"
#include "emulator_data.hpp"

using namespace pamc;

namespace {

// Random ramps and holds over [lo, hi] V (`--input random:SEED:LO:HI`) on the calibrated physics plant.
io::Measurement openLoopRecord(std::uint64_t seed, double seconds, double lo = -3.5, double hi = 4.0) {
  return testdata::emulatorRecord(sim::paperPlant(), seed, seconds, false, lo, hi);
}

// A model of `effects` fitted (Levenberg-Marquardt from spread starts) on a record over the whole stroke.
model::Model fitted(const std::vector<std::string>& effects) {
  static const io::Measurement d = openLoopRecord(1, 30.0);
  model::Model structure;
  for (const auto& e : effects) structure.addEffect(e);
  return ident::fit(structure, d, ident::FitSettings::forMethod(ident::FitMethod::MultiStart)).model;
}

// The pneumatic_balance model diagnose found on the calibrated physics plant (tools/mbc_table.py's final
// model, committed in tests/data/models).
const std::string kPneumaticFile =
    std::string(PAMC_SOURCE_DIR) + "/tests/data/models/calibrated_pneumatic_balance.json";

// `m` with a tenth of its gain k: a model that runs inside its range and moves ten times too little.
model::Model tenthOfTheGain(model::Model m) {
  auto p = m.params();
  p[0] *= 0.1;  // k: the output's gain
  m.setParams(p);
  return m;
}

// `run` on the calibrated physics plant through a controller of `kind` with `cfg` (its model set), the loop
// starting at the model's static inverse of the trajectory's first point.
sim::Record onPaperPlant(control::Kind kind, control::ControllerConfig cfg, const sim::ClosedLoopRun& run) {
  plant::PlantConfig pc = sim::paperPlant();
  cfg.u_min = pc.u_min;
  cfg.u_max = pc.u_max;
  auto c = control::makeController(kind, cfg);
  plant::Plant p(pc);
  control::InverseStatic inv;
  inv.build(cfg.model, cfg.u_min, cfg.u_max, cfg.Ts);
  return sim::runClosedLoop(*c, p, run, inv(run.home()));
}

sim::Record track(control::Kind kind, const model::Model& m, const sim::ClosedLoopRun& run,
                  const estimation::ActiveModelSettings& ukf = {}) {
  control::ControllerConfig cfg;
  cfg.model = m;
  cfg.ukf = ukf;
  return onPaperPlant(kind, cfg, run);
}

double rmseFrom(const sim::Record& r, double from) {
  double s = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < r.t.size(); ++i)
    if (r.t[i] >= from) s += (r.yd[i] - r.y[i]) * (r.yd[i] - r.y[i]), ++n;
  return std::sqrt(s / static_cast<double>(n));
}

sim::ClosedLoopRun triangle() {
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::triangle(0.05, 0.2, 30.0);
  run.duration_s = 40.0;
  return run;
}

// A rig's loop at 50 Hz on the plant `pc` (its period set here), the MBC's model the committed `file`
// (tests/data/models/) or `m`.
constexpr double kFiftyHertz = 0.02;
control::ControllerConfig atFiftyHertz(plant::PlantConfig& pc, const model::Model& m) {
  pc.Ts = kFiftyHertz;
  control::ControllerConfig cfg;
  cfg.Ts = kFiftyHertz;
  cfg.u_min = pc.u_min;
  cfg.u_max = pc.u_max;
  cfg.model = m;
  return cfg;
}
control::ControllerConfig atFiftyHertz(plant::PlantConfig& pc, const std::string& file) {
  return atFiftyHertz(pc, io::readModelFile(std::string(PAMC_SOURCE_DIR) + "/tests/data/models/" + file));
}

// `run` (a second's pre-roll added) on `pc` through a controller of `kind`, from the vented muscle (-5 V).
sim::Record fromVented(control::Kind kind, const control::ControllerConfig& cfg, const plant::PlantConfig& pc,
                       sim::ClosedLoopRun run) {
  run.preroll_s = 1.0;
  auto c = control::makeController(kind, cfg);
  plant::Plant p(pc);
  return sim::runClosedLoop(*c, p, run, -5.0);
}

// The MBC with `cfg` on the physics plant, tracking the paper's triangle (or `traj`) from rest, one cycle per
// step().
class MbcOnTriangle {
 public:
  explicit MbcOnTriangle(const control::ControllerConfig& cfg,
                         const control::Trajectory& traj = control::Trajectory::triangle(0.05, 0.2, 30.0))
      : c_(control::makeController(control::Kind::Mbc, cfg)),
        p_(sim::paperPlant()),
        traj_(traj),
        ahead_(c_->lookahead()) {
    p_.reset(0.0);
    c_->activate(0.0, p_.measure());
  }
  // Cycle k: the position measured (y), the controller's output, the plant moved by it.
  control::ControlOutput step(int k, double& y) {
    y = p_.measure();
    const auto o = c_->update(traj_.at(k * 1e-3), aheadAt(k), y);
    p_.step(o.u, 0.0);
    return o;
  }
  double aheadAt(int k) const { return traj_.at((k + ahead_) * 1e-3); }
  double setpointAt(int k) const { return traj_.at(k * 1e-3); }

 private:
  std::unique_ptr<control::Controller> c_;
  plant::Plant p_;
  control::Trajectory traj_;
  int ahead_;
};

}  // namespace

// The physics plant's triangle (the paper's 0.05 Hz, 0.2-30 mm) with models fitted on one whole-stroke
// record, each richer than the last (the rungs `pamc diagnose` climbs on such a record): ordered by their
// validated RMSE on a second record, the MBC's triangle RMSE does not rise from one to the next (issue 36:
// "along the diagnose ladder its triangle RMSE does not rise"), and with the plain reference model it is
// not worse than 1.05x the PI's.
TEST(Mbc, AModelThatValidatesBetterTracksBetterAndThePlainOneCostsNothing) {
  const auto run = triangle();
  const io::Measurement val = openLoopRecord(2, 15.0);
  const double pi = rmseFrom(track(control::Kind::PI, fitted({}), run), 1.0);
  std::vector<std::pair<double, double>> rungs;  // (validated RMSE, MBC triangle RMSE)
  for (const auto& effects : std::vector<std::vector<std::string>>{{}, {"saturation"}, {"saturation", "force_loop"}}) {
    const auto m = fitted(effects);
    rungs.emplace_back(ident::rmseFrom(m, val), rmseFrom(track(control::Kind::Mbc, m, run), 1.0));
    std::printf("%zu effects: validated %.4f mm, MBC triangle %.4f mm (PI %.4f)\n", effects.size(), rungs.back().first,
                rungs.back().second, pi);
  }
  EXPECT_LE(rungs.front().second, 1.05 * pi);
  std::sort(rungs.begin(), rungs.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  for (size_t i = 1; i < rungs.size(); ++i) EXPECT_LE(rungs[i].second, rungs[i - 1].second) << "rung " << i;
}

// A model whose inverse folds (docs/CONTROL.md, "A model whose inverse folds"): the plain Bouc-Wen core the
// calibrated physics plant's whole-stroke record gave (tools/mbc_table.py's reference model: k rho 5.70
// against k (1 - rho) -6.25) turns against its command where h crosses 0 - the fold where the MBC's
// feedforward jumped by 0.4 V and the muscle ran 2.2 mm off; a paper-like core (k 5, rho 0.8: its h term
// with the u term's sign) and a straight one do not fold, nor does the paper-like core behind a lag.
TEST(Mbc, ModelInverseFoldsWhereItsCoreTurnsAgainstItsCommand) {
  model::Model folding;
  folding.core() = {-0.5490247625371758, -10.387188504931045, 18.71960379664081, 1.0,
                    1.0740840248218628,  0.09017424244531425};
  const model::InverseFold f = model::inverseFold(folding, -3.39, 3.99);
  EXPECT_TRUE(f.folds);
  EXPECT_LT(f.least, -0.05);
  EXPECT_GT(f.gain, 3.0);
  EXPECT_GT(f.at_input, -3.39);
  EXPECT_LT(f.at_input, 3.99);
  model::Model paper;
  paper.core() = {5.0, 0.8, 20.0, 1.0, 0.3, 0.3};
  const model::InverseFold p = model::inverseFold(paper, -3.5, 4.0);
  EXPECT_FALSE(p.folds);
  EXPECT_GT(p.least, 0.5);
  model::Model straight;
  straight.core() = {5.0, 1.0, 20.0, 1.0, 0.3, 0.3};
  EXPECT_NEAR(model::inverseFold(straight, -3.5, 4.0).least, 1.0, 1e-9);
  EXPECT_FALSE(model::inverseFold(folding, 3.0, 3.0).folds);  // no range: nothing to judge
  // A lag before the core goes on past each reversal of a swept command; that is no fold (the second plant's
  // pressure_lag rungs were taken for folding at their range's edges, least slope -1.06, while their cores
  // swept alone do not fold).
  model::Model lagged = paper;
  lagged.addEffect("pressure_lag");
  lagged.setEffectParam("pressure_lag", "tau", 0.2);
  lagged.setEffectParam("pressure_lag", "slew", 5.0);
  EXPECT_FALSE(model::inverseFold(lagged, -3.5, 4.0).folds);
}

// Outside the model's output range the feedforward is off (u_c = 0) and the PI runs alone; at the
// switches the command does not jump by more than the PI's own step.
TEST(Mbc, OutsideTheModelsRangeThePiRunsAloneAndTheSwitchIsBumpless) {
  model::Model m = fitted({});
  model::OperatingRange r = m.range();
  ASSERT_TRUE(r.known);
  r.output = {10.0, 20.0};
  m.setRange(r);
  control::ControllerConfig cfg;
  cfg.model = m;
  MbcOnTriangle loop(cfg);
  int off = 0, on = 0, switches = 0;
  double u_prev = 0.0, worst_jump_at_switch = 0.0, y = 0.0;
  bool was_on = false;
  for (int k = 0; k < 20000; ++k) {
    const double yd_ahead = loop.aheadAt(k);
    const auto o = loop.step(k, y);
    ASSERT_TRUE(std::isfinite(o.u));
    const bool is_on = o.u_c != 0.0;
    if (yd_ahead < 9.0 || yd_ahead > 21.0) {
      EXPECT_FALSE(is_on) << "t " << k * 1e-3 << " yd ahead " << yd_ahead;
    }
    (is_on ? on : off)++;
    if (k > 0 && is_on != was_on)
      ++switches, worst_jump_at_switch = std::max(worst_jump_at_switch, std::fabs(o.u - u_prev));
    was_on = is_on;
    u_prev = o.u;
  }
  EXPECT_GT(on, 2000);
  EXPECT_GT(off, 2000);
  EXPECT_GE(switches, 3);
  EXPECT_LT(worst_jump_at_switch, 0.1) << "V";
}

// A model identified on a narrow record (the paper's u0 reaches 4.6-28.75 mm) driven over the whole
// stroke, and a model that is plainly wrong (its gain a tenth of the plant's): every command finite, no
// cycle reports the estimator as failed. The narrow model falls back to the PI where it does not hold and
// costs at most 1.05x the PI's error. The wrong one is inside its range everywhere and is trusted: it was to
// stay within twice the PI's error and does not (0.90 against 0.31 mm with the default error filter; 0.82
// before the feedforward was held at the edge of the input range, 0.76 before its filter's lost cycles were
// left out of the modelling error) - printed, a known miss
// (docs/CONTROL.md): nothing in the MBC yet tells a model that is wrong where it claims to hold.
TEST(Mbc, AModelUsedWhereItDoesNotHoldDoesNotCostTheRun) {
  const auto run = triangle();
  const double pi = rmseFrom(track(control::Kind::PI, fitted({}), run), 1.0);
  const model::Model wrong = tenthOfTheGain(fitted({}));
  const model::Model narrow = ident::fit(model::Model{}, openLoopRecord(3, 20.0, -0.5, 0.5),
                                         ident::FitSettings::forMethod(ident::FitMethod::MultiStart))
                                  .model;
  int n_model = 0;
  for (const model::Model& m : {narrow, wrong}) {
    control::ControllerConfig cfg;
    cfg.model = m;
    auto c = control::makeController(control::Kind::Mbc, cfg);
    plant::Plant plant(sim::paperPlant());
    plant.reset(0.0);
    c->activate(0.0, plant.measure());
    const int ahead = c->lookahead();
    double s = 0.0;
    size_t n = 0;
    for (int k = 0; k < 40000; ++k) {
      const double yd = run.reference.at(k * 1e-3), y = plant.measure();
      const auto o = c->update(yd, run.reference.at((k + ahead) * 1e-3), y);
      ASSERT_TRUE(std::isfinite(o.u)) << k;
      ASSERT_FALSE(o.estimator_reset) << k;
      if (k >= 1000) s += (yd - y) * (yd - y), ++n;
      plant.step(o.u, 0.0);
    }
    std::printf("%s model: triangle RMSE %.4f mm (PI %.4f)\n", n_model == 0 ? "narrow" : "wrong", std::sqrt(s / n), pi);
    // Both within the 1.05x the PI's for a model that does not hold. The wrong one tracked at 0.90 mm
    // (PI 0.31) before the response monitor took its feedforward off.
    EXPECT_LE(std::sqrt(s / n), 1.05 * pi);
    ++n_model;
  }
}

// The response monitor (detail::ResponseMonitor) on the MBC's own cycle: with a model of a tenth of the
// plant's gain it takes the feedforward off (u_c = 0) and says by how much more the muscle moves than the
// model - beyond the break-even of 2; with the model diagnose found on the plant (the committed
// pneumatic_balance) it never does. (The plain Bouc-Wen model fitted there loses it at its folds.)
TEST(Mbc, AModelThatMovesOtherwiseThanTheMuscleLosesItsFeedforward) {
  const auto run = triangle();
  const std::vector<model::Model> models{io::readModelFile(kPneumaticFile), tenthOfTheGain(fitted({}))};
  for (size_t i = 0; i < models.size(); ++i) {
    control::ControllerConfig cfg;
    cfg.model = models[i];
    auto c = control::makeController(control::Kind::Mbc, cfg);
    plant::Plant plant(sim::paperPlant());
    plant.reset(0.0);
    c->activate(0.0, plant.measure());
    int distrusted = 0, first = -1;
    double ratio = NAN;
    for (int k = 0; k < 40000; ++k) {
      const double y = plant.measure();
      const auto o = c->update(run.reference.at(k * 1e-3), run.reference.at((k + c->lookahead()) * 1e-3), y);
      if (o.model_distrusted) {
        EXPECT_EQ(o.u_c, 0.0) << k;
        if (first < 0) first = k, ratio = o.model_ratio;
        ++distrusted;
      }
      plant.step(o.u, 0.0);
    }
    std::printf("%s model: distrusted in %d of 40000 cycles, from %d at a ratio of %.3g\n",
                i == 0 ? "diagnosed" : "wrong", distrusted, first, ratio);
    if (i == 0) {
      EXPECT_EQ(distrusted, 0);
    } else {
      EXPECT_GT(distrusted, 30000);  // from its first verdict on, two windows (2 s) after the start at the earliest
      EXPECT_GT(ratio, 2.0);
    }
  }
}

// pneumatic_balance as `pamc diagnose` found it on the calibrated physics plant's whole-stroke record
// (tools/mbc_table.py's final model, validated 0.095 mm, tests/data/models), the MBC on the triangle with
// the estimator in each of its forms for such a model (ActiveModelSettings::Q_d).
struct PneumaticOnTriangle {
  explicit PneumaticOnTriangle(double Q_d) {
    const model::Model m = io::readModelFile(kPneumaticFile);
    estimation::ActiveModelSettings s;
    s.Q_d = Q_d;
    const auto r = track(control::Kind::Mbc, m, triangle(), s);
    double se = 0.0;
    int n = 0;
    for (size_t i = 0; i < r.t.size(); ++i) {
      EXPECT_TRUE(std::isfinite(r.u[i])) << i;
      if (std::fabs(r.y_hat[i] - r.y[i]) > 1.0) ++lost;
      if (r.t[i] < 1.0) continue;
      worst = std::max(worst, std::fabs(r.yd[i] - r.y[i]));
      se += (r.yd[i] - r.y[i]) * (r.yd[i] - r.y[i]);
      ++n;
    }
    rmse = std::sqrt(se / n);
    std::printf("Q_d %g: lost %d cycles, RMSE %.4f mm, largest error %.3f mm\n", Q_d, lost, rmse, worst);
  }
  int lost = 0;  // cycles whose posterior missed the position by more than 1 mm
  double worst = 0.0, rmse = 0.0;
};

// The estimator's form that carries such a model (its modelling error on the position): it follows the
// plant all the way, and the MBC meets issue 36's bounds on this row against the PI's (the largest error
// at most the PI's, the RMSE at most half of it).
TEST(Mbc, APneumaticModelIsCarriedByItsEstimator) {
  const PneumaticOnTriangle mbc(estimation::ActiveModelSettings{}.Q_d);
  const auto pi = track(control::Kind::PI, fitted({}), triangle());
  double pi_worst = 0.0, se = 0.0;
  int n = 0;
  for (size_t i = 0; i < pi.t.size(); ++i)
    if (pi.t[i] >= 1.0) {
      pi_worst = std::max(pi_worst, std::fabs(pi.yd[i] - pi.y[i]));
      se += (pi.yd[i] - pi.y[i]) * (pi.yd[i] - pi.y[i]);
      ++n;
    }
  std::printf("PI: RMSE %.4f mm, largest error %.3f mm\n", std::sqrt(se / n), pi_worst);
  EXPECT_EQ(mbc.lost, 0);
  EXPECT_LE(mbc.worst, pi_worst);
  EXPECT_LE(mbc.rmse, 0.5 * std::sqrt(se / n));
}

// The other form (h, f_h and the model's output states in the filter) loses the plant with this model -
// its posterior sticks at the model's rest and misses the position by millimetres - and a modelling error
// followed from it aimed the feedforward 5 mm off when it came back in: a 22.8 mm excursion. Not followed
// while the posterior misses the position by more than 1 mm, the loop stays on the triangle: every
// command finite, no error above 5 mm (chosen: a sixth of the stroke; the PI's own largest is 1.2 mm).
TEST(Mbc, AModelItsEstimatorLosesDoesNotThrowThePayload) {
  const PneumaticOnTriangle mbc(0.0);
  EXPECT_GT(mbc.lost, 1000);  // the filter does lose the plant here
  EXPECT_LT(mbc.worst, 5.0) << "mm";
}

// At 50 Hz, as a rig node runs: the calibrated physics plant sampled every 20 ms, the commands two cycles on
// the bus, the loop started from a vented muscle (-5 V, below the model's input range) with a second's
// pre-roll, the committed pneumatic model on the triangle. The MBC tracks better than the PI, scored over
// the whole run as `pamc rig run` scores it (start included). With the horizon of the commands in flight
// plus one sample, its feedforward stayed out (the inverse at the command's limits) and it tracked worse
// than the PI (docs/CONTROL.md, "At 50 Hz").
TEST(Mbc, AtFiftyHertzTheFeedforwardComesInAndTracksBetterThanThePi) {
  constexpr double kTs = 0.02;
  plant::PlantConfig pc = sim::paperPlant();
  pc.Ts = kTs;
  control::ControllerConfig cfg;
  cfg.Ts = kTs;
  cfg.u_min = pc.u_min;
  cfg.u_max = pc.u_max;
  cfg.model = io::readModelFile(kPneumaticFile);
  sim::ClosedLoopRun run = triangle();
  run.preroll_s = 1.0;
  double rmse[2] = {0.0, 0.0};
  int ff_on = 0;
  for (int i = 0; i < 2; ++i) {
    auto c = control::makeController(i == 0 ? control::Kind::PI : control::Kind::Mbc, cfg);
    plant::Plant p(pc);
    const auto r = sim::runClosedLoop(*c, p, run, -5.0);
    double se = 0.0;
    for (size_t k = 0; k < r.t.size(); ++k) {
      ASSERT_TRUE(std::isfinite(r.u[k])) << k;
      se += (r.yd[k] - r.y[k]) * (r.yd[k] - r.y[k]);
      if (i == 1 && r.u_c[k] != 0.0) ++ff_on;
    }
    rmse[i] = std::sqrt(se / static_cast<double>(r.t.size()));
  }
  std::printf("50 Hz: PI %.4f mm, MBC %.4f mm, feedforward in %d of 2000 cycles\n", rmse[0], rmse[1], ff_on);
  EXPECT_GT(ff_on, 1000);
  EXPECT_LT(rmse[1], rmse[0]);
}

// The same user's loop on the calibrated plant: the model diagnose learnt from the paper's u0 recorded at 50 Hz
// (`pamc rig run --plant CAL --input sine:0.1:0.2:2.9 --period-us 20000 --preroll 1 --duration 40 --out
// u0.csv`, u1 the same with 1.4 V; `pamc diagnose u0.csv --validate u1.csv`: creep + pneumatic_balance,
// validated 0.167 mm; tests/data/models/calibrated_u0_50hz_diagnosed.json). Under a held command at 20 ms it
// swings against its lower stop in a cycle of three samples - nothing in a record of a moving sinusoid asks it
// not to - and the MBC's inverse of it swung the valve: the triangle at 1.34 mm, 11.8 mm at worst, against the
// PI's 0.364. A model that does not come to rest leaves the PI alone: bound, the issue's "never worse than 1.05x
// PI" and no feedforward in any cycle. At 1 kHz the same model comes to rest.
TEST(Mbc, AModelThatDoesNotComeToRestLeavesThePiAlone) {
  plant::PlantConfig pc = sim::paperPlant();
  control::ControllerConfig cfg = atFiftyHertz(pc, "calibrated_u0_50hz_diagnosed.json");
  const model::HeldRest rest = control::mbcModelRest(cfg);
  EXPECT_FALSE(rest.rests) << model::describeHeldRest(rest);
  EXPECT_FALSE(control::mbcGovernor(cfg).rate_mm_s > 0.0);
  const double pi = rmseFrom(fromVented(control::Kind::PI, cfg, pc, triangle()), 0.0);
  const auto r = fromVented(control::Kind::Mbc, cfg, pc, triangle());
  const auto ff_on = std::count_if(r.u_c.begin(), r.u_c.end(), [](double u) { return u != 0.0; });
  std::printf("a model that does not rest at 50 Hz: PI %.4f mm, MBC %.4f mm, feedforward in %ld cycles\n", pi,
              rmseFrom(r, 0.0), static_cast<long>(ff_on));
  EXPECT_EQ(ff_on, 0);
  EXPECT_LE(rmseFrom(r, 0.0), 1.05 * pi);
  cfg.Ts = 1e-3;
  EXPECT_TRUE(control::mbcModelRest(cfg).rests) << model::describeHeldRest(control::mbcModelRest(cfg));
}

// The loop of a user with a rig (tools/vcan_model_loop.sh), without the bus: the default physics plant at
// 50 Hz, the muscle vented (-5 V, below the input range of [-2.7, 3.1] V the model was identified on), a
// second's pre-roll, the triangle, and the model diagnose learnt from the paper's u0 recorded over vcan
// (tests/data/models/default_u0_over_vcan.json). From -5 V the PI's integral rises through the
// muscle's first millimetres, where its gain is highest, and the loop swings between 0 and 25 mm for
// 6 s (3.13 mm over the run). The MBC starts its PI at the edge of the command range its model knows:
// bound, chosen before the run, the 0.5x the PI's triangle RMSE, scored over the whole run.
TEST(Mbc, FromAVentedMuscleItStartsAtTheEdgeOfItsModelsInputRange) {
  constexpr double kTs = 0.02;
  plant::PlantConfig pc = plant::PlantConfig::defaults();
  pc.Ts = kTs;
  control::ControllerConfig cfg;
  cfg.Ts = kTs;
  cfg.u_min = pc.u_min;
  cfg.u_max = pc.u_max;
  cfg.model = io::readModelFile(std::string(PAMC_SOURCE_DIR) + "/tests/data/models/default_u0_over_vcan.json");
  ASSERT_TRUE(cfg.model.range().known);
  sim::ClosedLoopRun run = triangle();
  run.preroll_s = 1.0;
  double rmse[2] = {0.0, 0.0};
  for (int i = 0; i < 2; ++i) {
    auto c = control::makeController(i == 0 ? control::Kind::PI : control::Kind::Mbc, cfg);
    plant::Plant p(pc);
    const auto r = sim::runClosedLoop(*c, p, run, -5.0);
    rmse[i] = rmseFrom(r, 0.0);
  }
  std::printf("from -5 V at 50 Hz: PI %.4f mm, MBC %.4f mm\n", rmse[0], rmse[1]);
  EXPECT_LE(rmse[1], 0.5 * rmse[0]);

  auto mbc = control::makeController(control::Kind::Mbc, cfg);
  mbc->activate(-5.0, 0.0);
  EXPECT_GE(mbc->integral(), cfg.model.range().input.lo);
  cfg.model.setRange({});  // a model without a range: the command in effect, as the PI
  mbc = control::makeController(control::Kind::Mbc, cfg);
  mbc->activate(-5.0, 0.0);
  EXPECT_EQ(mbc->integral(), -5.0);
}

// At 1 kHz from the vented muscle (the calibrated plant, its committed pneumatic model, a second's
// pre-roll): to fill the muscle fast the inverse asks for more than the model's input range. Switched
// off there, the feedforward left its last value in the PI's integral (bumpless) and the muscle filled to
// 27 mm; the triangle's RMSE over the run was 0.37 mm against the PI's 0.34. Held at the range's edge
// instead, it fills as the model knows. Bound, chosen before the run: the 0.5x the PI's.
TEST(Mbc, AFeedforwardBeyondItsModelsInputRangeIsHeldAtTheRangesEdge) {
  plant::PlantConfig pc = sim::paperPlant();
  control::ControllerConfig cfg;
  cfg.u_min = pc.u_min;
  cfg.u_max = pc.u_max;
  cfg.model = io::readModelFile(kPneumaticFile);
  const auto& range = cfg.model.range().input;
  sim::ClosedLoopRun run = triangle();
  run.preroll_s = 1.0;
  double rmse[2] = {0.0, 0.0};
  for (int i = 0; i < 2; ++i) {
    const auto kind = i == 0 ? control::Kind::PI : control::Kind::Mbc;
    auto c = control::makeController(kind, cfg);
    plant::Plant p(pc);
    const auto r = sim::runClosedLoop(*c, p, run, -5.0);
    rmse[i] = rmseFrom(r, 0.0);
    for (size_t k = 0; k < r.t.size() && kind == control::Kind::Mbc; ++k) {
      if (r.u_c[k] == 0.0) continue;
      ASSERT_TRUE(range.contains(r.u_c[k])) << "t " << r.t[k] << " feedforward " << r.u_c[k];
    }
  }
  std::printf("from -5 V at 1 kHz: PI %.4f mm, MBC %.4f mm\n", rmse[0], rmse[1]);
  EXPECT_LE(rmse[1], 0.5 * rmse[0]);
}

TEST(Mbc, HorizonIsAboveTheCommandsInFlight) {
  control::ControllerConfig cfg;
  EXPECT_GT(control::mbcHorizon(cfg), cfg.delay_cycles);
  cfg.mbc.horizon = 2;
  EXPECT_THROW(control::makeController(control::Kind::Mbc, cfg), std::invalid_argument);
  EXPECT_EQ(control::kindFromString("mbc"), control::Kind::Mbc);
}

// Beside a feedforward the PI's integral is a correction that may span the command's whole difference:
// switching a 5 V feedforward in at a command of -2 V moves the integral to -7 V, and the next cycle
// keeps it there (clamped to the command's range, the switch would jump by 2 V).
TEST(Mbc, ThePisIntegralBesideAFeedforwardSpansTheCommandsDifference) {
  control::ControllerConfig cfg;
  control::detail::PiCore alone, beside;
  alone.configure(cfg);
  beside.configure(cfg, true);
  for (auto* pi : {&alone, &beside}) {
    pi->reset(-2.0);
    pi->shift(-5.0);
  }
  EXPECT_DOUBLE_EQ(beside.nominal(0.0), -7.0);
  EXPECT_DOUBLE_EQ(alone.nominal(0.0), cfg.u_min);
}

// The setpoint governor by hand: a 15 mm jump is taken within the rate and the acceleration and arrived at
// without overshoot, in about the time a trapezoid of those limits takes (15/60 + 60/600 = 0.35 s); a ramp
// slower than the rate passes without lag; rate 0 passes the setpoint as it is.
TEST(Mbc, TheSetpointGovernorTakesAJumpWithinItsLimitsAndPassesARamp) {
  constexpr double Ts = 1e-3, rate = 60.0, accel = 600.0;
  control::detail::SetpointGovernor g;
  g.configure(rate, accel, Ts);
  g.reset(10.0);
  double r_prev = 10.0, v_prev = 0.0, peak = 0.0;
  int arrived = -1;
  for (int k = 0; k < 1000; ++k) {
    const double r = g.step(25.0), v = (r - r_prev) / Ts;
    EXPECT_LE(std::fabs(v), rate + 1e-9) << k;
    EXPECT_LE(std::fabs(v - v_prev), accel * Ts + 1e-9) << k;
    peak = std::max(peak, r);
    if (arrived < 0 && std::fabs(r - 25.0) < 0.01) arrived = k;
    r_prev = r, v_prev = v;
  }
  EXPECT_LE(peak, 25.0 + 0.01);
  EXPECT_NEAR(arrived * Ts, 15.0 / rate + rate / accel, 0.05);
  // The triangle's slope, 3 mm/s, passes: after the start the lag is within one sample's travel (0.003 mm).
  g.reset(0.2);
  double lag = 0.0;
  for (int k = 0; k < 3000; ++k) lag = 0.2 + 3.0 * (k + 1) * Ts - g.step(0.2 + 3.0 * (k + 1) * Ts);
  EXPECT_LE(std::fabs(lag), 3.0 * Ts + 1e-6);
  g.configure(0.0, accel, Ts);
  EXPECT_EQ(g.step(17.5), 17.5);
  // Lowered below a ramp's slope (to a slow model's pace, 5 mm/s) and given the fixed rate as what still
  // counts as a ramp, it passes a 20 mm/s ramp: after its start it is caught up with, not left behind.
  g.configure(5.0, 300.0, Ts, rate);
  g.reset(0.0);
  for (int k = 0; k < 3000; ++k) lag = 20.0 * (k + 1) * Ts - g.step(20.0 * (k + 1) * Ts);
  EXPECT_LE(std::fabs(lag), 20.0 * Ts + 1e-6);
}

// A lower acceleration asked for mid-move is taken once the follower is at rest: at it, a follower braking at
// the higher one could no longer stop on the target. A higher one is taken at once.
TEST(Mbc, TheSetpointGovernorLowersItsAccelerationOnlyAtRest) {
  constexpr double Ts = 1e-3, rate = 60.0, fast = 1800.0, slow = 600.0;
  control::detail::SetpointGovernor g;
  g.configure(rate, fast, Ts);
  g.reset(10.0);
  double peak = 0.0;
  int lowered = -1, arrived = -1;
  for (int k = 0; k < 1000; ++k) {
    if (k >= 250) g.setAccel(slow);  // as it starts to brake (it arrives in about 0.28 s)
    const double r = g.step(25.0);
    peak = std::max(peak, r);
    if (lowered < 0 && g.accel() == slow) lowered = k;
    if (arrived < 0 && std::fabs(r - 25.0) < 0.01) arrived = k;
  }
  EXPECT_LE(peak, 25.0 + 0.01);
  ASSERT_GE(arrived, 0);
  EXPECT_GE(lowered, arrived - 1);
  g.setAccel(fast);
  EXPECT_EQ(g.accel(), fast);
}

// The model's pace is its own: a payload that rings twice as slowly behind a core that answers at once moves
// the position half as fast with a quarter of the acceleration; the plain model answers at once and has
// none. The governor's limits are the fixed ones, lowered to a quarter of a slower model's pace.
TEST(Mbc, TheGovernorSlowsToAQuarterOfASlowModelsPace) {
  auto ringing = [](double fn) {
    model::Model m;
    m.addEffect("mass_spring");
    m.setEffectParam("mass_spring", "fn", fn);
    m.setEffectParam("mass_spring", "zeta", 0.7);
    return m;
  };
  const control::ModelPace fast = control::modelPace(ringing(1.0), -3.0, 3.0);
  const control::ModelPace slow = control::modelPace(ringing(0.5), -3.0, 3.0);
  std::printf("pace: fn 1 Hz %.2f mm/s %.2f mm/s^2, fn 0.5 Hz %.2f mm/s %.2f mm/s^2\n", fast.speed, fast.accel,
              slow.speed, slow.accel);
  ASSERT_GT(fast.speed, 0.0);
  EXPECT_NEAR(slow.speed / fast.speed, 0.5, 0.03);
  EXPECT_NEAR(slow.accel / fast.accel, 0.25, 0.03);
  EXPECT_EQ(control::modelPace(model::Model{}, -3.0, 3.0).speed, 0.0);

  control::ControllerConfig cfg;
  const double fixed_rate = cfg.mbc.rate_mm_s, fixed_accel = cfg.mbc.accel_mm_s2;
  for (double fn : {0.5, 50.0}) {
    cfg.model = ringing(fn);
    const control::ModelPace p = control::modelPace(cfg.model, cfg.u_min, cfg.u_max);
    const control::GovernorLimits g = control::mbcGovernor(cfg);
    std::printf("fn %g Hz: pace %.1f mm/s %.0f mm/s^2, governor %.1f mm/s %.0f mm/s^2\n", fn, p.speed, p.accel,
                g.rate_mm_s, g.accel_mm_s2);
    EXPECT_DOUBLE_EQ(g.rate_mm_s, std::min(fixed_rate, 0.25 * p.speed));
    EXPECT_DOUBLE_EQ(g.accel_mm_s2, std::min(fixed_accel, 0.25 * p.accel));
    EXPECT_EQ(g.from_model, fn < 1.0);  // the slow one is below the fixed limits, the fast one above
  }
  cfg.model = model::Model{};
  EXPECT_FALSE(control::mbcGovernor(cfg).from_model);
  EXPECT_EQ(control::mbcGovernor(cfg).rate_mm_s, fixed_rate);
  cfg.mbc.rate_mm_s = 0.0;
  EXPECT_EQ(control::mbcGovernor(cfg).rate_mm_s, 0.0);
}

// The square wave on the physics plant with the committed pneumatic model. Its inverse followed a secant
// slope near 0 on a filling step and flew between the edges of its input range, cycle after cycle: 96 %
// overshoot, no step settled (`pamc experiments` on the calibrated plant, docs/CONTROL.md). With the next
// command kept between two that missed on either side of the target, every step settles, within issue 36's
// 2 %.
TEST(Mbc, TheInversesBracketKeepsTheSquareWaveFromRinging) {
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::square(0.1, 10.0, 25.0);
  run.duration_s = 30.0;
  const sim::Record mbc = track(control::Kind::Mbc, io::readModelFile(kPneumaticFile), run);
  for (int dir : {+1, -1}) {
    const auto c = sim::stepResponse(mbc, dir, 1.0, 0.02);
    std::printf("square %s: MBC %.2f %% %.3f s, %d of %d steps unsettled\n", dir > 0 ? "forward" : "backward",
                c.overshoot_pct, c.settling_s, c.unsettled, c.steps);
    ASSERT_GT(c.steps, 0);
    EXPECT_LE(c.overshoot_pct, 2.0);
    EXPECT_EQ(c.unsettled, 0);
  }
}

// A square wave on the physics plant with the model fitted on the whole-stroke record: the steps are
// taken through the governor and overshoot less than with the setpoint as it is (mbc_rate 0), where the
// short-horizon inverse drives the payload past the setpoint.
TEST(Mbc, TheGovernorTakesTheOvershootOutOfASquareWave) {
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::square(0.1, 10.0, 25.0);
  run.duration_s = 20.0;
  const model::Model m = fitted({"saturation", "force_loop"});
  auto overshoot = [&](double rate) {
    control::ControllerConfig cfg;
    cfg.model = m;
    cfg.mbc.rate_mm_s = rate;
    const auto r = onPaperPlant(control::Kind::Mbc, cfg, run);
    const auto up = sim::stepResponse(r, +1, 1.0, 0.02), down = sim::stepResponse(r, -1, 1.0, 0.02);
    return std::max(up.overshoot_pct, down.overshoot_pct);
  };
  const double governed = overshoot(control::ControllerConfig{}.mbc.rate_mm_s), raw = overshoot(0.0);
  control::ControllerConfig cfg;
  cfg.model = m;
  const control::GovernorLimits g = control::mbcGovernor(cfg);
  std::printf(
      "square wave overshoot: governed %.2f %% (%.1f mm/s, %.0f mm/s^2; the model's pace %.0f mm/s, %.0f "
      "mm/s^2), raw %.2f %%\n",
      governed, g.rate_mm_s, g.accel_mm_s2, g.pace.speed, g.pace.accel, raw);
  EXPECT_LT(governed, 5.0);
  EXPECT_LT(governed, 0.5 * raw);
}

// The square wave of the paper's levels on the physics plant through the MBC with model m, its governor's
// acceleration while the model carries the loop set to `carried` [mm/s^2].
static sim::Record squareWave(const model::Model& m, double carried) {
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::square(0.1, 10.0, 25.0);
  run.duration_s = 30.0;
  control::ControllerConfig cfg;
  cfg.model = m;
  cfg.mbc.accel_carried_mm_s2 = carried;
  return onPaperPlant(control::Kind::Mbc, cfg, run);
}

// The governor's acceleration at each step of that square wave (from rest at 0 mm: the first at 0 s).
static std::vector<double> accelAtSteps(const model::Model& m) {
  control::ControllerConfig cfg;
  cfg.model = m;
  MbcOnTriangle loop(cfg, control::Trajectory::square(0.1, 10.0, 25.0));
  std::vector<double> at;
  double y = 0.0;
  for (int k = 0; k < 30000; ++k) {
    const auto o = loop.step(k, y);
    if (k == 0 || loop.aheadAt(k) != loop.aheadAt(k - 1)) at.push_back(o.governor_accel);
  }
  return at;
}

// The governor's faster acceleration is taken only while the model carries the loop. With the committed
// pneumatic model (diagnose's final model of this plant: the PI's integral beside it stays within 1 % of the
// command's span) every step of the square wave is taken at it, and the steps settle sooner than at the
// fixed acceleration, within 2 % overshoot. The same model said to hold only above -1.5 V (model.json's
// range) has its feedforward held at that edge at the lower level, which needs -2.2 V, and the PI's
// integral makes up the rest - the paper's u0 record's model on this plant (docs/CONTROL.md): from its first
// visit there on, every step is taken at the fixed acceleration.
TEST(Mbc, TheGovernorIsFasterOnlyWhileTheModelCarriesTheLoop) {
  const control::ControllerConfig defaults;
  const double fixed = defaults.mbc.accel_mm_s2;
  const model::Model good = io::readModelFile(kPneumaticFile);
  control::ControllerConfig cfg;
  cfg.model = good;
  const control::GovernorLimits g = control::mbcGovernor(cfg);
  ASSERT_GT(g.accel_carried_mm_s2, g.accel_mm_s2);
  const sim::Record fast = squareWave(good, defaults.mbc.accel_carried_mm_s2), slow = squareWave(good, fixed);
  for (int dir : {+1, -1}) {
    const auto f = sim::stepResponse(fast, dir, 1.0, 0.02), s = sim::stepResponse(slow, dir, 1.0, 0.02);
    std::printf("square %s, the final model: %.3f s %.2f %% (at %.0f mm/s^2: %.3f s %.2f %%)\n",
                dir > 0 ? "forward" : "backward", f.settling_s, f.overshoot_pct, fixed, s.settling_s, s.overshoot_pct);
    ASSERT_GT(f.steps, 0);
    EXPECT_LT(f.settling_s, s.settling_s - 0.02);
    EXPECT_LE(f.overshoot_pct, 2.0);
    EXPECT_EQ(f.unsettled, 0);
  }
  const std::vector<double> carried = accelAtSteps(good);
  ASSERT_EQ(carried.size(), 7u);  // from rest at 0 mm to 25 mm, then 10, 25, 10, 25, 10, 25 mm
  for (size_t i = 1; i < carried.size(); ++i) EXPECT_EQ(carried[i], g.accel_carried_mm_s2) << "step " << i;
  model::Model narrow = good;
  model::OperatingRange r = narrow.range();
  r.input.lo = -1.5;
  narrow.setRange(r);
  const std::vector<double> held = accelAtSteps(narrow);
  ASSERT_EQ(held.size(), 7u);
  EXPECT_EQ(held[1], g.accel_carried_mm_s2);  // down from 25 mm, where the model carries the loop
  for (size_t i = 2; i < held.size(); ++i) EXPECT_EQ(held[i], g.accel_mm_s2) << "step " << i;
}

// `pamc experiments` says where the MBC's feedforward was in the command: summary.json's
// table2/<row>/mbc/feedforward_share and a line under Table 2. With the committed pneumatic model all of the
// triangle; with its gain cut to a tenth, only the cycles before the response monitor's verdict.
TEST(Mbc, ExperimentsSayWhereTheFeedforwardWasInTheCommand) {
  const model::Model wrong = tenthOfTheGain(io::readModelFile(kPneumaticFile));
  const auto dir = std::filesystem::temp_directory_path() / "pamc_test_mbc_share";
  std::filesystem::create_directories(dir);
  const std::string wrong_file = (dir / "wrong.json").string();
  io::writeModelFile(wrong_file, wrong);
  double share[2] = {0.0, 0.0};
  for (int i = 0; i < 2; ++i) {
    sim::ExperimentSettings s;
    s.model_file = i == 0 ? kPneumaticFile : wrong_file;
    s.only = {"triangle"};
    s.figures = false;
    s.out_dir = (dir / (i == 0 ? "good" : "wrong")).string();
    const auto r = sim::runExperiments(s);
    share[i] = r.json["table2"]["triangle_0.05Hz"]["mbc"]["feedforward_share"].get<double>();
    EXPECT_NE(r.text.find("MBC's feedforward in the command, share of the scored cycles: triangle_0.05Hz"),
              std::string::npos);
    // The governor's limits in effect are in the readings: the model's pace (656 mm/s) is above the fixed
    // limits; with a tenth of its gain the model moves slower, and a quarter of its pace is below them.
    const auto& gov = r.json["readings"]["mbc_governor"];
    EXPECT_EQ(gov["lowered_to_the_models_pace"].get<bool>(), i == 1);
    if (i == 0) {
      EXPECT_EQ(gov["rate_mm_s"].get<double>(), 60.0);
    } else {
      EXPECT_LT(gov["rate_mm_s"].get<double>(), 60.0);
    }
  }
  std::printf("feedforward in the command: %.3f with the model, %.3f with a tenth of its gain\n", share[0], share[1]);
  EXPECT_EQ(share[0], 1.0);
  EXPECT_LT(share[1], 0.2);
  std::filesystem::remove_all(dir);
}

// The user's loop at 50 Hz on the calibrated plant, with the model check in diagnose: the paper's u0 and u1
// recorded over the in-process bus at 20 ms (the commands of Mbc.AModelThatDoesNotComeToRestLeavesThePiAlone,
// tests/data/records). Diagnose no longer takes a model that swings under a held command (it validated at
// 0.167 mm and swung the MBC's valve); the ladder ends at one that comes to rest, and the MBC with it tracks the
// triangle better than the PI (bound, chosen as the other 50 Hz tests': below the PI's RMSE; 0.255 against 0.364
// mm over the bus).
TEST(Mbc, AtFiftyHertzDiagnoseGivesTheMbcAModelThatComesToRest) {
  const std::string dir = std::string(PAMC_SOURCE_DIR) + "/tests/data/records/";
  const io::Measurement u0 = io::readMeasurementCsv(dir + "calibrated_50hz_u0.csv");
  const io::Measurement u1 = io::readMeasurementCsv(dir + "calibrated_50hz_u1.csv");
  diagnose::DiagnoseSettings s;
  s.seed = 1;
  s.probes = false;
  const auto d = diagnose::diagnose(u0, &u1, s);
  ASSERT_NEAR(u0.Ts, kFiftyHertz, 1e-9);
  plant::PlantConfig pc = sim::paperPlant();
  const control::ControllerConfig cfg = atFiftyHertz(pc, d.ladder.back().model);
  const model::HeldRest rest = control::mbcModelRest(cfg);
  EXPECT_TRUE(rest.rests) << model::describeHeldRest(rest);
  const double pi = rmseFrom(fromVented(control::Kind::PI, cfg, pc, triangle()), 0.0);
  const double mbc = rmseFrom(fromVented(control::Kind::Mbc, cfg, pc, triangle()), 0.0);
  std::printf("50 Hz, the model of u0 (%s, validated %.4f mm): PI %.4f mm, MBC %.4f mm\n",
              d.ladder.back().model.describe().c_str(), d.ladder.back().rmse_val, pi, mbc);
  EXPECT_LT(mbc, pi);
}

// The default physics plant at 50 Hz, whose static gain is about 12 mm/V in the muscle's first millimetres,
// with the model diagnose learnt from its u0 over vcan: the commands in flight delay the loop by 70 ms, and
// with the paper's 1 kHz gains the PI's integral swung the square wave's 10 mm level between 0 and 25 mm (MBC
// and PI alike: 58-67 % overshoot). Scaled to the model's slope at the setpoint (Mbc::gainShare), the MBC's PI
// holds it. Bound: issue 36's 2 % forward and backward, chosen before the run; the PI's beside it.
TEST(Mbc, ThePisGainsFollowTheMusclesStiffnessAtFiftyHertz) {
  plant::PlantConfig pc = plant::PlantConfig::defaults();
  const control::ControllerConfig cfg = atFiftyHertz(pc, "default_u0_over_vcan.json");
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::square(0.1, 10.0, 25.0);
  run.duration_s = 40.0;
  double worst[2] = {0.0, 0.0};
  for (int i = 0; i < 2; ++i) {
    const auto r = fromVented(i == 0 ? control::Kind::PI : control::Kind::Mbc, cfg, pc, run);
    const auto up = sim::stepResponse(r, +1, 1.0, 0.02), down = sim::stepResponse(r, -1, 1.0, 0.02);
    worst[i] = std::max(up.overshoot_pct, down.overshoot_pct);
  }
  std::printf("default plant, 50 Hz, square wave: largest overshoot PI %.1f %%, MBC %.2f %%\n", worst[0], worst[1]);
  EXPECT_LE(worst[1], 2.0);
}

// The plain reference model diagnose fits on the calibrated plant's whole stroke (tools/mbc_table.py's rung 0,
// committed as tests/data/models/calibrated_whole_stroke_plain.json) folds: its output turns against its
// command where h crosses 0, and the feedforward jumped there by 0.33 V in 4 ms - the triangle's largest error
// 2.16 mm against the PI's 1.16. Its feedforward now crosses the fold at the setpoint's pace while the model
// does not carry the loop (Mbc::heldAtFold). Bound: issue 36's 1.05x the PI's, for the largest error as for the
// RMSE.
TEST(Mbc, AFoldingModelsFeedforwardCrossesItsFoldAtTheSetpointsPace) {
  control::ControllerConfig cfg;
  cfg.model = io::readModelFile(std::string(PAMC_SOURCE_DIR) + "/tests/data/models/calibrated_whole_stroke_plain.json");
  cfg.u_min = sim::paperPlant().u_min;
  cfg.u_max = sim::paperPlant().u_max;
  const model::Interval u = control::mbcCommandRange(cfg);
  ASSERT_TRUE(model::inverseFold(cfg.model, u.lo, u.hi).folds);
  const auto run = triangle();
  double rmse[2], worst[2];
  for (int i = 0; i < 2; ++i) {
    const auto r = track(i == 0 ? control::Kind::PI : control::Kind::Mbc, cfg.model, run);
    rmse[i] = rmseFrom(r, 1.0);
    worst[i] = 0.0;
    for (size_t k = 0; k < r.t.size(); ++k)
      if (r.t[k] >= 1.0) worst[i] = std::max(worst[i], std::fabs(r.yd[k] - r.y[k]));
  }
  std::printf("the folding plain model: PI %.4f / %.3f mm, MBC %.4f / %.3f mm (RMSE / largest)\n", rmse[0], worst[0],
              rmse[1], worst[1]);
  EXPECT_LE(rmse[1], 1.05 * rmse[0]);
  EXPECT_LE(worst[1], 1.05 * worst[0]);
}

// The check itself (model::heldRest): every committed model comes to rest at 1 kHz and at 50 Hz, its largest
// swing far inside the 2 % band; the model diagnosed at 50 Hz swings over a third of its span there. A swing
// measured over a hold's last quarter: a model held at a command settles within it, so none is seen.
TEST(Mbc, TheHeldRestCheckTellsAModelThatSwingsFromOnesThatSettle) {
  const std::string dir = std::string(PAMC_SOURCE_DIR) + "/tests/data/models/";
  for (const char* f : {"calibrated_pneumatic_balance.json", "default_u0_over_vcan.json",
                        "oracle_pneumatic_balance.json", "oracle_u0_diagnosed.json"}) {
    const model::Model m = io::readModelFile(dir + f);
    for (double Ts : {1e-3, 0.02}) {
      const model::HeldRest r = model::heldRest(m, Ts, m.range().input.lo, m.range().input.hi);
      EXPECT_TRUE(r.rests) << f << " at " << Ts << ": " << model::describeHeldRest(r);
      EXPECT_LT(r.swing, 0.001 * r.span) << f;
    }
  }
  const model::Model swings = io::readModelFile(dir + "calibrated_u0_50hz_diagnosed.json");
  const model::HeldRest r = model::heldRest(swings, 0.02, swings.range().input.lo, swings.range().input.hi);
  EXPECT_FALSE(r.rests);
  EXPECT_GT(r.swing, 0.3 * r.span) << model::describeHeldRest(r);
  EXPECT_TRUE(model::heldRest(model::Model(), 0.02, -1.0, 1.0).rests);  // the paper's Bouc-Wen core answers at once
  // A payload's ringing comes to rest where it decays at zeta wn >= 0.84 /s (held_rest.cpp): at 2 Hz, damping
  // ratios of 0.1 and 0.03 on either side of 0.067.
  for (const double zeta : {0.1, 0.03}) {
    model::Model ringing;
    ringing.addEffect("mass_spring");
    ringing.setEffectParam("mass_spring", "fn", 2.0);
    ringing.setEffectParam("mass_spring", "zeta", zeta);
    EXPECT_EQ(model::heldRest(ringing, 1e-3, -1.0, 1.0).rests, zeta > 0.067) << zeta;
  }
}
