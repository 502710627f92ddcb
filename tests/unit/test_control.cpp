#include <gtest/gtest.h>

#include <cmath>

#include "control/controller.hpp"
#include "ident/identify.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"
#include "control/trajectory.hpp"

#include <nlohmann/json.hpp>

using namespace pamc;

namespace {
// An open-loop emulator run as the measurement the identification reads (1 kHz).
template <class Run>
io::Measurement measurementOf(const Run& r) {
  io::Measurement d;
  d.source = "emulator";
  d.t = r.t;
  d.u = r.u;
  d.y = r.y;
  d.Ts = 1e-3;
  return d;
}

// A reference model identified on the emulator once for all tests of this file.
const model::Model& identified() {
  static const model::Model m = [] {
    plant::Plant p(plant::PlantConfig::modelDefaults());
    const auto r = sim::runOpenLoopInput(p, control::Trajectory::sine(0.1, 2.9, 0.2), 20.0);
    const io::Measurement d = measurementOf(r);
    ident::FitSettings s;
    s.ga.max_generations = 60;
    return ident::fit(model::Model{}, d, s).model;
  }();
  return m;
}

sim::Record run(control::Kind kind, const sim::ClosedLoopRun& run, const control::ControllerConfig& base = {}) {
  control::ControllerConfig cfg = base;
  cfg.model = identified();
  auto c = control::makeController(kind, cfg);
  plant::Plant p(plant::PlantConfig::modelDefaults());
  control::InverseStatic inv;
  inv.build(cfg.model, cfg.u_min, cfg.u_max, cfg.Ts);
  return sim::runClosedLoop(*c, p, run, inv(run.reference.at(0)));
}

double meanAbsError(const sim::Record& r, double from) {
  double s = 0;
  int n = 0;
  for (size_t i = 0; i < r.t.size(); ++i)
    if (r.t[i] >= from) {
      s += std::fabs(r.yd[i] - r.y[i]);
      ++n;
    }
  return s / n;
}
}  // namespace

class ClosesTheLoop : public ::testing::TestWithParam<control::Kind> {};

// Each feedback controller settles on a step of the setpoint held long enough, on the full
// emulator (every effect on, noise, one cycle of bus delay).
// 20 s at 25 mm, then 20 s at 10 mm; the mean absolute error of the last 3 s of each half.
std::pair<double, double> settledErrors(control::Kind kind, const control::ControllerConfig& cfg = {}) {
  sim::ClosedLoopRun r;
  r.reference = control::Trajectory::square(0.025, 10.0, 25.0);
  r.duration_s = 40.0;
  const auto rec = run(kind, r, cfg);
  double e1 = 0, e2 = 0;
  int n1 = 0, n2 = 0;
  for (size_t i = 0; i < rec.t.size(); ++i) {
    if (rec.t[i] > 17 && rec.t[i] < 20) e1 += std::fabs(rec.yd[i] - rec.y[i]), ++n1;
    if (rec.t[i] > 37) e2 += std::fabs(rec.yd[i] - rec.y[i]), ++n2;
  }
  for (double u : rec.u)
    if (u < -5.0 || u > 5.0) ADD_FAILURE() << "command " << u << " V outside the valve's range";
  return {e1 / n1, e2 / n2};
}

// (The ESO in pamc's own first-order form: the paper's form, the default, settles through a slow mode
// that the next test measures.)
TEST_P(ClosesTheLoop, SettlesAfterAStep) {
  control::ControllerConfig cfg;
  cfg.eso.order = 1;
  const auto [e1, e2] = settledErrors(GetParam(), cfg);
  EXPECT_LT(e1, 0.05) << control::toString(GetParam());
  EXPECT_LT(e2, 0.05) << control::toString(GetParam());
}

// The ESO as printed (eq. 22's double integrator) on this nearly static plant: a slow (period about
// 60 s), weakly damped mode in which the PI integral and the ESO's disturbance estimate trade the
// static command (docs/CONTROL.md); it converges, but not within these 20 s to PI's accuracy - and
// pamc's own first-order form does.
TEST(EsoForms, PrintedFormSettlesSlowlyTheFirstOrderFormLikePi) {
  control::ControllerConfig printed;
  printed.eso.order = 2;
  printed.ki = 1.3;  // the PI integral docs/CONTROL.md describes the mode with (ki 3, the default since, damps it)
  const auto [p1, p2] = settledErrors(control::Kind::PidEso, printed);
  EXPECT_LT(p1, 1.5);
  EXPECT_LT(p2, 1.5);
  EXPECT_GT(std::max(p1, p2), 0.05) << "the printed form's slow mode is gone: docs/CONTROL.md is out of date";
}

// The first-order ESO on its own nominal plant (a lag of gain K and time constant T) with a constant
// output disturbance d: x2 converges to d / T and the compensation cancels it, u_c = -d / K; at
// activation it takes over the holding command without a bump.
TEST(EsoForms, FirstOrderObserverEstimatesAConstantDisturbance) {
  control::ControllerConfig c;
  c.eso.order = 1;
  c.ki = 0.0;
  c.kp = 0.0;  // the compensation alone
  c.delay_cycles = 0;
  auto eso = control::makeController(control::Kind::PidEso, c);
  const double K = c.eso.gain, T = c.eso.tau, d = 3.0, u0 = 1.0;
  double x = K * u0;  // the plant at rest under u0, before the disturbance
  eso->activate(u0, x);
  auto o = eso->update(x, x, x);
  EXPECT_NEAR(o.u, u0, 1e-9) << "bumpless activation";
  double u = o.u;
  for (int k = 0; k < 60000; ++k) {  // 60 s: 30 time constants of the observer
    x += 1e-3 * (K * u - x) / T;
    o = eso->update(x + d, x + d, x + d);
    u = o.u;
  }
  EXPECT_NEAR(eso->disturbance(), d / T, 1e-3 * d / T);
  EXPECT_NEAR(o.u_c, -d / K, 1e-3);
  EXPECT_NEAR(x + d, K * u0, 1e-3) << "the output is back where u0 held it";
}

TEST_P(ClosesTheLoop, TracksASlowSineBetterThanOpenLoop) {
  sim::ClosedLoopRun r;
  r.reference = control::Trajectory::sine(0.05, 8.0, 18.0);
  r.duration_s = 40.0;
  const auto closed = run(GetParam(), r);
  const auto open = run(control::Kind::OpenLoop, r);
  EXPECT_LT(meanAbsError(closed, 20.0), meanAbsError(open, 20.0)) << control::toString(GetParam());
}

INSTANTIATE_TEST_SUITE_P(Feedback, ClosesTheLoop,
                         ::testing::Values(control::Kind::PI, control::Kind::PidEso, control::Kind::PiAmc,
                                           control::Kind::Mbc),
                         [](const auto& info) { return std::string(control::toString(info.param)); });

// Open loop through the inverse static characteristic lands near a held setpoint (within the
// hysteresis it cannot see).
TEST(OpenLoop, InverseStaticLandsNearSetpoint) {
  sim::ClosedLoopRun r;
  r.reference = control::Trajectory::constant(15.0);
  r.duration_s = 3.0;
  const auto rec = run(control::Kind::OpenLoop, r);
  EXPECT_LT(meanAbsError(rec, 2.0), 4.0);
}

// Anti-windup: a setpoint beyond the stroke saturates the valve; when it comes back the PI
// recovers within a second instead of unwinding a huge integral.
TEST(AntiWindup, RecoversQuicklyAfterSaturation) {
  sim::ClosedLoopRun r;
  r.reference = control::Trajectory::square(0.05, 15.0, 60.0);  // 60 mm is unreachable
  r.duration_s = 16.0;
  control::ControllerConfig cfg;
  cfg.ki = 1.5;
  const auto rec = run(control::Kind::PI, r, cfg);
  // Saturated at the top during the first half.
  EXPECT_DOUBLE_EQ(rec.u[static_cast<size_t>(9000)], 5.0);
  // Back within 0.5 mm of 15 mm by 4 s after the setpoint returns.
  EXPECT_LT(std::fabs(rec.y[static_cast<size_t>(14000)] - 15.0), 0.5);
}

// A command the loop limited (its slew after a restart) is the one that went out: the PI-based
// controllers do not integrate against it, as at saturation, and the estimators' history holds it.
TEST(AntiWindup, ACommandTheLoopLimitedIsNotIntegratedAgainst) {
  for (const auto kind : {control::Kind::PI, control::Kind::PiAmc, control::Kind::PidEso, control::Kind::Mbc}) {
    SCOPED_TRACE(control::toString(kind));
    control::ControllerConfig cfg;
    cfg.ki = 3.0;
    auto held = control::makeController(kind, cfg);
    auto free = control::makeController(kind, cfg);
    held->activate(-2.0, 10.0);
    free->activate(-2.0, 10.0);
    const double i0 = held->integral();
    for (int k = 0; k < 500; ++k) {  // 5 mm short of the setpoint for 0.5 s, the command held at -2 V
      (void)free->update(15.0, 15.0, 10.0);
      (void)held->update(15.0, 15.0, 10.0);
      held->limited(-2.0);
    }
    // 5 mm x 3 V/(mm s) x 0.5 s = 7.5 V of integral without the limit (within the integral's bounds).
    EXPECT_GT(free->integral(), held->integral() + 1.0) << "integrated against the limit as without it";
    // The MBC's integral also takes over its feedforward where that switches (bumpless), so only the
    // forms without a feedforward are held exactly.
    if (kind != control::Kind::Mbc) {
      EXPECT_LE(held->integral(), i0 + 1e-9) << "integrated against the limit";
    }
  }
}

TEST(Config, RejectsBadSettings) {
  control::ControllerConfig c;
  c.u_min = 5;
  c.u_max = -5;
  EXPECT_THROW(control::makeController(control::Kind::PI, c), std::invalid_argument);
  control::ControllerConfig d;
  d.kp = NAN;
  EXPECT_THROW(control::makeController(control::Kind::PI, d), std::invalid_argument);
  EXPECT_THROW(control::kindFromString("lqr"), std::invalid_argument);
}

// Issue item "back into the controller": on an emulator with a strong pressure lag, the predictive
// AMC tracks better with the model that includes the lag than with the plain Bouc-Wen model (both
// identified on the same open-loop record; same gains, automatic horizon).
namespace {
plant::PlantConfig laggingPlant() {
  return plant::PlantConfig::fromJson(
      nlohmann::json::parse(R"({"kind":"model","effects":{"pressure_lag":{"enabled":true,"tau":0.12,"slew":1000},
      "load":{"enabled":false},"saturation":{"enabled":false},"friction_hysteresis":{"enabled":false},
      "mass_spring":{"enabled":false}},"stroke":{"enabled":false}})"),
      "test plant");
}

model::Model fitOnLaggingPlant(const std::vector<std::string>& effects) {
  plant::Plant p(laggingPlant());
  const auto r = sim::runOpenLoopInput(p, control::Trajectory::parse("random:1:-3:3"), 30.0);
  const io::Measurement d = measurementOf(r);
  model::Model structure;
  for (const auto& e : effects) structure.addEffect(e);
  ident::FitSettings s;
  s.ga.max_generations = 40;
  return ident::fit(structure, d, s).model;
}

double predictiveAmcRmse(const model::Model& m, double hz) {
  control::ControllerConfig cfg;
  cfg.model = m;
  cfg.amc_inverse = 1.0;
  cfg.amc_horizon = 0;
  auto c = control::makeController(control::Kind::PiAmc, cfg);
  plant::Plant p(laggingPlant());
  control::InverseStatic inv;
  inv.build(cfg.model, cfg.u_min, cfg.u_max, cfg.Ts);
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::sine(hz, 15.0, 20.0);
  run.duration_s = 15.0;
  const auto rec = sim::runClosedLoop(*c, p, run, inv(run.reference.at(0)));
  // Against the true position: sensor noise is the same for both models and no model removes it.
  double s = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < rec.t.size(); ++i)
    if (rec.t[i] >= 2.0) {
      s += (rec.yd[i] - rec.y_true[i]) * (rec.yd[i] - rec.y_true[i]);
      ++n;
    }
  return std::sqrt(s / static_cast<double>(n));
}
}  // namespace

TEST(AmcModel, ResponseHorizonFollowsTheModelsDynamics) {
  const model::Model plain = identified();
  model::Model lag = plain;
  lag.addEffect("pressure_lag");
  lag.setEffectParam("pressure_lag", "tau", 0.1);
  lag.setEffectParam("pressure_lag", "slew", 1000.0);
  EXPECT_LE(control::modelResponseSamples(plain, 1e-3, -5, 5, 0.1), 2);
  const int n = control::modelResponseSamples(lag, 1e-3, -5, 5, 0.1);
  EXPECT_NEAR(n, 0.1 * std::log(1.0 / 0.9) * 1000.0, 3.0);  // 10 % of a first-order response: tau ln(1/0.9)
}

TEST(AmcModel, DiagnosedModelTracksBetterThanPlainBoucWen) {
  const model::Model plain = fitOnLaggingPlant({});
  const model::Model lag = fitOnLaggingPlant({"pressure_lag"});
  for (double hz : {0.05, 0.1}) {
    const double e_plain = predictiveAmcRmse(plain, hz), e_lag = predictiveAmcRmse(lag, hz);
    RecordProperty("rmse_plain_" + std::to_string(hz), std::to_string(e_plain));
    RecordProperty("rmse_lag_" + std::to_string(hz), std::to_string(e_lag));
    // 2.8x / 1.9x at 0.05 / 0.1 Hz with the exact Bouc-Wen step (the plain fit on random steps gained
    // most from it); the margin was 2x with the Euler sub-steps.
    EXPECT_LT(e_lag * 1.5, e_plain) << hz << " Hz: plain " << e_plain << " mm, with pressure_lag " << e_lag << " mm";
  }
}

// The paper's AMC read bus-aware (eq. 17 through the commands still on the bus, a Smith predictor).
// Decided before it ran: on the model plant its square wave would overshoot less than eq. (17) as printed,
// whose compensation feeds back on itself through the delay. It does not (docs/EXPERIMENTS.md, "The
// paper's AMC, bus-aware"): with the plain model on a plant with a pressure lag the model lacks it
// overshoots more (10.0 against 7.2 mm); on the physics plant it overshoots less. Pinned here, so that a
// change of either shows: on a plant that is the model itself both land without overshoot (its RMSE
// against the printed form's goes either way with the model: 0.80 against 0.83 mm for the default core,
// 0.83 against 0.76 for this identified one); on the model plant it overshoots more.
namespace {
double largestOvershoot(const sim::Record& rec, double lo, double hi) {
  double over = 0.0;
  for (size_t i = 0; i < rec.t.size(); ++i) {
    if (rec.t[i] < 1.0) continue;  // the start from rest
    if (rec.yd[i] == hi) over = std::max(over, rec.y[i] - hi);
    if (rec.yd[i] == lo) over = std::max(over, lo - rec.y[i]);
  }
  return over;
}

// The plain model's own plant: its core, no effects, no stroke ends, no sensor noise.
plant::PlantConfig plantOfTheModel(const model::Model& m) {
  auto j = plant::PlantConfig::modelDefaults().toJson();
  const auto& c = m.core();
  j["core"] = {{"k", c.k}, {"rho", c.rho}, {"b", c.b}, {"alpha", c.alpha}, {"beta", c.beta}, {"gamma", c.gamma}};
  for (auto& [name, e] : j["effects"].items()) e["enabled"] = false;
  j["stroke"]["enabled"] = false;
  j["sensor"]["noise"] = false;
  j["sensor"]["quantization"] = false;
  return plant::PlantConfig::fromJson(j, "the model's own plant");
}

sim::Record squareWith(const control::ControllerConfig& cfg, const plant::PlantConfig& pc) {
  sim::ClosedLoopRun r;
  r.reference = control::Trajectory::square(0.1, 10.0, 25.0);
  r.duration_s = 20.0;
  auto c = control::makeController(control::Kind::PiAmc, cfg);
  plant::Plant p(pc);
  control::InverseStatic inv;
  inv.build(cfg.model, cfg.u_min, cfg.u_max, cfg.Ts);
  return sim::runClosedLoop(*c, p, r, inv(r.reference.at(0)));
}
}  // namespace

TEST(AmcBusAware, OnTheModelsOwnPlantNoOvershootOnTheModelPlantMoreThanAsPrinted) {
  control::ControllerConfig printed, bus;
  printed.model = bus.model = identified();
  bus.amc_bus_aware = true;
  const auto own = plantOfTheModel(identified());
  const auto own_printed = squareWith(printed, own), own_bus = squareWith(bus, own);
  EXPECT_LT(largestOvershoot(own_bus, 10.0, 25.0), 0.01);
  EXPECT_LT(largestOvershoot(own_printed, 10.0, 25.0), 0.01);
  const auto plant = plant::PlantConfig::modelDefaults();
  const double o_printed = largestOvershoot(squareWith(printed, plant), 10.0, 25.0);
  const double o_bus = largestOvershoot(squareWith(bus, plant), 10.0, 25.0);
  EXPECT_GT(o_bus, o_printed) << "the model plant's miss changed: bus-aware " << o_bus << " mm, printed " << o_printed;
  EXPECT_EQ(control::makeController(control::Kind::PiAmc, bus)->lookahead(), bus.delay_cycles + 1);
  bus.amc_inverse = 0.5;
  EXPECT_THROW(control::makeController(control::Kind::PiAmc, bus), std::invalid_argument);
}
