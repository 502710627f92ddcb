// Tests of the independent continuous-time plant (src/physics): convergence in the ODE step, the reference
// mode against closed-form solutions of the Bouc-Wen equation, rest states, end stops, the sensor, the
// configuration file, the allocation-free cycle, and the existing PI gains closing the loop on the rig.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common/count_allocations.hpp"
#include "physics/physics_plant.hpp"

using pamc::physics::Mode;
using pamc::physics::PhysicsConfig;
using pamc::physics::PhysicsPlant;

namespace {

constexpr double kPi = 3.14159265358979323846;

PhysicsConfig quiet(Mode mode) {
  PhysicsConfig c = PhysicsConfig::defaults();
  c.mode = mode;
  c.noise_std_mm = 0.0;
  c.quantum_mm = 0.0;
  return c;
}

// A test record at 1 kHz: holds, steps, a chirp up to 6 Hz, a slow sine, and a load signal.
struct Record {
  std::vector<double> u, f;
};

Record testRecord(double amplitude = 1.0) {
  Record r;
  const int n = 7000;
  for (int i = 0; i < n; ++i) {
    const double t = i * 1e-3;
    double u;
    if (t < 0.3)
      u = 0.0;
    else if (t < 0.8)
      u = 2.0;
    else if (t < 1.3)
      u = -2.0;
    else if (t < 1.5)
      u = 0.5;
    else if (t < 3.5) {
      // Linear chirp 0.5 -> 6 Hz over 2 s.
      const double tc = t - 1.5;
      u = 1.5 * std::sin(2.0 * kPi * (0.5 * tc + (6.0 - 0.5) / (2.0 * 2.0) * tc * tc));
    } else if (t < 6.0) {
      u = 2.5 * std::sin(2.0 * kPi * 0.4 * (t - 3.5));
    } else {
      u = 1.0;  // hold
    }
    r.u.push_back(amplitude * u);
    r.f.push_back(t < 2.0 ? 0.0 : (t < 4.0 ? 40.0 : 15.0));
  }
  return r;
}

std::vector<double> simulate(const PhysicsConfig& c, const Record& r) {
  PhysicsPlant p(c);
  p.reset(r.u[0], r.f[0]);
  std::vector<double> y;
  y.reserve(r.u.size());
  for (size_t i = 0; i < r.u.size(); ++i) y.push_back(p.step(r.u[i], r.f[i]));
  return y;
}

double maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0.0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
  return m;
}

double span(const std::vector<double>& y) {
  const auto mm = std::minmax_element(y.begin(), y.end());
  return *mm.second - *mm.first;
}

// Halving the ODE step changes the sampled output by far less than the sensor noise.
void expectStepConverged(PhysicsConfig c, const std::string& what) {
  const double tol = 0.1 * PhysicsConfig::defaults().noise_std_mm;
  const Record r = testRecord();
  const auto y1 = simulate(c, r);
  if (c.mode == Mode::Rig)
    c.substeps *= 2;
  else
    c.reference_substeps *= 2;
  const auto y2 = simulate(c, r);
  EXPECT_LT(maxAbsDiff(y1, y2), tol) << what;
  // The record moves the output (a frozen plant would pass the comparison).
  EXPECT_GT(span(y1), 5.0) << what;
}

// Effects switched on one at a time, with parameters that make each visible in the test record.
PhysicsConfig withEffect(Mode mode, const std::string& name) {
  nlohmann::json j = {{"mode", mode == Mode::Rig ? "rig" : "reference"}};
  nlohmann::json e = {{"enabled", true}};
  if (name == "delay") e["d"] = 0.0123;  // a fractional number of samples: the split substep
  if (name == "dead_band") e["threshold"] = -1.0;
  if (name == "pressure_lag") e["slew"] = 20.0;  // the slew limit is active in the steps
  if (name == "warm_up") {
    e["tau"] = 2.0;
    e["shift"] = 1.0;
  }
  if (name == "creep") e["tau"] = 0.5;
  if (name == "force_loop") e["delta"] = 0.05;
  j["effects"] = {{name, e}};
  PhysicsConfig c = PhysicsConfig::fromJson(j, "test");
  c.noise_std_mm = 0.0;
  c.quantum_mm = 0.0;
  return c;
}

const std::vector<std::string> kAllEffects = {"pressure_lag", "asymmetry",           "creep",  "mass_spring",
                                              "force_loop",   "friction_hysteresis", "delay",  "dead_band",
                                              "load",         "saturation",          "warm_up"};

}  // namespace

TEST(PhysicsStep, HalvingTheOdeStepChangesLittleRig) { expectStepConverged(quiet(Mode::Rig), "rig"); }

TEST(PhysicsStep, HalvingTheOdeStepChangesLittleRigWithEffects) {
  for (const char* n : {"creep", "delay", "dead_band", "warm_up"}) expectStepConverged(withEffect(Mode::Rig, n), n);
}

TEST(PhysicsStep, HalvingTheOdeStepChangesLittleReference) { expectStepConverged(quiet(Mode::Reference), "reference"); }

TEST(PhysicsStep, HalvingTheOdeStepChangesLittleReferenceEachEffect) {
  for (const auto& n : kAllEffects) expectStepConverged(withEffect(Mode::Reference, n), n);
}

// Too few substeps are visible in the same comparison: the test above can fail.
TEST(PhysicsStep, TooCoarseAStepIsDetected) {
  PhysicsConfig c = quiet(Mode::Reference);
  c.reference_substeps = 20;
  const Record r = testRecord();
  const auto y1 = simulate(c, r);
  c.reference_substeps = 40;
  const auto y2 = simulate(c, r);
  EXPECT_GT(maxAbsDiff(y1, y2), 0.1 * PhysicsConfig::defaults().noise_std_mm);
}

// Reference mode, effects off: loading from h = 0 and then unloading follow the closed-form solutions
// of the Bouc-Wen equation in the input, dh/dv = alpha - (beta + gamma) h (v rising, h >= 0) and
// dh/dv = alpha - (beta - gamma) h (v falling, h >= 0).
TEST(PhysicsReference, BoucWenMatchesClosedForm) {
  // The error is the ODE solver's (quadrature of the valve transients, summed over the record): below
  // 1e-5 mm at the default substeps, and 16 times smaller at twice as many.
  for (int refine : {1, 2}) {
    PhysicsConfig c = quiet(Mode::Reference);
    c.stroke_limits = false;
    c.reference_substeps *= refine;
    const double tol = refine == 1 ? 1e-5 : 1e-6;
    const auto& r = c.reference;
    PhysicsPlant p(c);
    const double v0 = -1.0, v1 = 1.5;
    p.reset(v0);
    const int n = 2000;
    double max_err = 0.0, h_top = 0.0;
    for (int i = 1; i <= n; ++i) {
      const double v = v0 + (v1 - v0) * i / n;
      const double y = p.step(v);
      const double h = r.alpha / (r.beta + r.gamma) * (1.0 - std::exp(-(r.beta + r.gamma) * (v - v0)));
      max_err = std::max(max_err, std::fabs(y - (r.k * r.rho * v + r.b + r.k * (1.0 - r.rho) * h)));
      h_top = h;
    }
    EXPECT_LT(max_err, tol) << "loading, substeps x" << refine;
    // Unloading from the top while h stays positive.
    const double c2 = r.beta - r.gamma, hinf = r.alpha / c2;
    max_err = 0.0;
    const double v2 = 0.5;
    for (int i = 1; i <= n; ++i) {
      const double v = v1 + (v2 - v1) * i / n;
      const double y = p.step(v);
      const double h = hinf + (h_top - hinf) * std::exp(-c2 * (v - v1));
      ASSERT_GT(h, 0.0);
      max_err = std::max(max_err, std::fabs(y - (r.k * r.rho * v + r.b + r.k * (1.0 - r.rho) * h)));
    }
    EXPECT_LT(max_err, tol) << "unloading, substeps x" << refine;
    // The loop is open: the output on the way down differs from the way up by millimetres.
    EXPECT_GT(std::fabs(r.k * (1.0 - r.rho) * h_top), 1.0);
  }
}

// y_k responds to the command u_k held over sample k (an open-loop DAQ record).
TEST(PhysicsReference, OutputRespondsWithinTheSample) {
  PhysicsConfig c = quiet(Mode::Reference);
  PhysicsPlant p(c);
  p.reset(0.0);
  const double y0 = p.position();
  const double y1 = p.step(1.0);
  EXPECT_GT(y1 - y0, 5.0);  // k rho = 11.25 mm/V, minus the hysteresis that starts to load
}

TEST(PhysicsReference, DelayShiftsTheResponseByD) {
  PhysicsConfig c = withEffect(Mode::Reference, "delay");
  c.effects.delay.d = 0.005;  // 5 samples
  PhysicsPlant p(c);
  p.reset(0.0);
  const double y0 = p.position();
  std::vector<double> y;
  for (int i = 0; i < 10; ++i) y.push_back(p.step(1.0));
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(y[static_cast<size_t>(i)], y0, 1e-12) << i;
  EXPECT_GT(y[5] - y0, 5.0);
}

TEST(PhysicsReference, LoadMovesTheOutputByComplianceTimesForce) {
  PhysicsConfig c = withEffect(Mode::Reference, "load");
  PhysicsPlant p(c);
  p.reset(0.0, 0.0);
  const double y0 = p.position();
  double y = 0.0;
  for (int i = 0; i < 5; ++i) y = p.step(0.0, 100.0);
  EXPECT_NEAR(y0 - y, c.effects.load.compliance * 100.0, 1e-9);
}

// Reset under a constant command is a rest state: holding the command keeps the position.
TEST(PhysicsRest, HoldingTheResetCommandKeepsThePosition) {
  struct Case {
    PhysicsConfig c;
    double u0, f;
    const char* what;
  };
  std::vector<Case> cases;
  for (double u0 : {-4.5, -1.0, 0.0, 1.7, 5.0}) cases.push_back({quiet(Mode::Rig), u0, 0.0, "rig"});
  cases.push_back({quiet(Mode::Rig), 0.3, 60.0, "rig with force"});
  PhysicsConfig rig_fx = quiet(Mode::Rig);
  rig_fx.effects.creep.enabled = rig_fx.effects.delay.enabled = rig_fx.effects.warm_up.enabled = true;
  cases.push_back({rig_fx, 0.7, 0.0, "rig with creep, delay, warm_up"});
  for (double u0 : {-2.0, 0.0, 1.0}) cases.push_back({quiet(Mode::Reference), u0, 0.0, "reference"});
  PhysicsConfig ref_fx = quiet(Mode::Reference);
  auto& e = ref_fx.effects;
  e.pressure_lag.enabled = e.asymmetry.enabled = e.creep.enabled = e.friction_hysteresis.enabled = true;
  e.delay.enabled = e.load.enabled = e.saturation.enabled = e.warm_up.enabled = e.mass_spring.enabled = true;
  cases.push_back({ref_fx, 1.0, 30.0, "reference with effects (mass_spring)"});
  PhysicsConfig ref_fl = ref_fx;
  ref_fl.effects.mass_spring.enabled = false;
  ref_fl.effects.force_loop.enabled = true;
  cases.push_back({ref_fl, -0.5, 30.0, "reference with effects (force_loop)"});
  for (const auto& k : cases) {
    PhysicsPlant p(k.c);
    p.reset(k.u0, k.f);
    const double y0 = p.position();
    double worst = 0.0;
    for (int i = 0; i < 2000; ++i) worst = std::max(worst, std::fabs(p.step(k.u0, k.f) - y0));
    EXPECT_LT(worst, 1e-9) << k.what << " u0 " << k.u0;
  }
}

// The rest state is the one the plant settles to: reset(u1) equals reset(u0) then u1 held long.
TEST(PhysicsRest, ResetIsWhereTheRigSettles) {
  PhysicsConfig c = quiet(Mode::Rig);
  c.muscle.hysteresis_N = c.muscle.hysteresis_N_per_bar = 0.0;  // no friction memory: one rest state
  c.payload.coulomb_N = 0.0;
  PhysicsPlant p(c);
  p.reset(-1.0);
  for (int i = 0; i < 5000; ++i) p.step(1.0);
  PhysicsPlant q(c);
  q.reset(1.0);
  EXPECT_NEAR(p.position(), q.position(), 1e-3);
  EXPECT_NEAR(p.pressure_bar(), q.pressure_bar(), 1e-3);
}

// The static map of the default rig: u = 0 near mid-stroke, [-3, 3] V sweeps most of the stroke,
// about 40 mm at 8 bar, monotone.
TEST(PhysicsRig, DefaultStaticMap) {
  PhysicsPlant p(quiet(Mode::Rig));
  double prev = -1.0;
  for (double u = -5.0; u <= 5.0; u += 0.5) {
    p.reset(u);
    EXPECT_GE(p.position(), prev) << u;
    prev = p.position();
  }
  p.reset(0.0);
  EXPECT_GT(p.position(), 15.0);
  EXPECT_LT(p.position(), 22.5);
  EXPECT_NEAR(p.pressure_bar(), 4.0, 1e-9);
  p.reset(-3.0);
  const double lo = p.position();
  p.reset(3.0);
  const double hi = p.position();
  EXPECT_GT(hi - lo, 0.75 * 40.0);
  p.reset(5.0);
  EXPECT_NEAR(p.pressure_bar(), 8.0, 1e-9);
  EXPECT_GT(p.position(), 37.0);
}

// The hysteresis of the rig: a slow triangle leaves a loop several millimetres wide.
TEST(PhysicsRig, SlowCycleShowsHysteresis) {
  PhysicsPlant p(quiet(Mode::Rig));
  p.reset(-3.0);
  const int n = 4000;
  double up = 0.0, down = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double y = p.step(-3.0 + 6.0 * i / n);
    if (i == n / 2) up = y;
  }
  for (int i = 0; i <= n; ++i) {
    const double y = p.step(3.0 - 6.0 * i / n);
    if (i == n / 2) down = y;
  }
  EXPECT_GT(down - up, 1.5);  // relaxing it stays more contracted than when contracting it
  EXPECT_LT(down - up, 10.0);
}

// Filling is flow-limited: a full-range command step needs tens of milliseconds, not one sample.
TEST(PhysicsRig, PressureRiseIsFlowLimited) {
  PhysicsPlant p(quiet(Mode::Rig));
  p.reset(-5.0);
  p.step(5.0);
  EXPECT_LT(p.pressure_bar(), 1.0);
  int k = 1;
  while (p.pressure_bar() < 7.2 && k < 2000) {
    p.step(5.0);
    ++k;
  }
  EXPECT_GT(k, 20);
  EXPECT_LT(k, 500);
}

TEST(PhysicsStops, RigStaysWithinTheStroke) {
  PhysicsConfig c = quiet(Mode::Rig);
  c.stroke_max_mm = 30.0;
  PhysicsPlant p(c);
  p.reset(0.0);
  double lo = 1e9, hi = -1e9;
  for (int k = 0; k < 6; ++k)
    for (int i = 0; i < 700; ++i) {
      const double y = p.step(k % 2 ? -5.0 : 5.0);
      lo = std::min(lo, y);
      hi = std::max(hi, y);
    }
  EXPECT_EQ(lo, 0.0);  // reached and never passed
  EXPECT_EQ(hi, 30.0);
}

TEST(PhysicsStops, ReferenceStaysWithinTheStroke) {
  PhysicsConfig c = quiet(Mode::Reference);
  PhysicsPlant p(c);
  p.reset(0.0);
  double lo = 1e9, hi = -1e9;
  for (double u : {-5.0, 5.0, -3.0, 4.0}) {
    const double y = p.step(u);
    lo = std::min(lo, y);
    hi = std::max(hi, y);
  }
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, 40.0);
}

TEST(PhysicsCommand, ClampedAndNonFiniteHeld) {
  PhysicsPlant a(quiet(Mode::Reference)), b(quiet(Mode::Reference));
  a.reset(0.0);
  b.reset(0.0);
  EXPECT_EQ(a.step(12.0), b.step(5.0));
  EXPECT_EQ(a.step(std::nan("")), b.step(5.0));
  EXPECT_EQ(a.step(-1e300), b.step(-5.0));
  EXPECT_EQ(a.step(INFINITY), b.step(-5.0));
}

TEST(PhysicsSensor, NoiseStdAsConfigured) {
  for (double sd : {0.004, 0.02}) {
    PhysicsConfig c = PhysicsConfig::defaults();
    c.noise_std_mm = sd;
    PhysicsPlant p(c);
    p.reset(0.0);
    const double y = p.position();
    double s2 = 0.0;
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
      const double e = p.measure() - y;
      s2 += e * e;
    }
    EXPECT_NEAR(std::sqrt(s2 / n), sd, 0.1 * sd);
  }
}

TEST(PhysicsSensor, ReadingsAreMultiplesOfTheQuantum) {
  for (double q : {0.001, 0.01}) {
    PhysicsConfig c = PhysicsConfig::defaults();
    c.quantum_mm = q;
    PhysicsPlant p(c);
    p.reset(0.3);
    int distinct_steps = 0;
    double prev = p.measure();
    for (int i = 0; i < 3000; ++i) {
      p.step(0.3 + std::sin(i * 1e-2));
      const double m = p.measure();
      EXPECT_NEAR(m / q, std::round(m / q), 1e-6) << m;
      if (m != prev) ++distinct_steps;
      prev = m;
    }
    EXPECT_GT(distinct_steps, 1000);
  }
}

TEST(PhysicsConfigJson, UnknownKeyIsNamed) {
  try {
    PhysicsConfig::fromJson({{"muscle", {{"diameter_mm", 20.0}, {"lenght_mm", 200.0}}}}, "rig.json");
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("rig.json"), std::string::npos) << m;
    EXPECT_NE(m.find("'lenght_mm'"), std::string::npos) << m;
    EXPECT_NE(m.find("length_mm"), std::string::npos) << m;  // the known keys are listed
  }
  EXPECT_THROW(PhysicsConfig::fromJson({{"bogus", 1}}, "f"), std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"effects", {{"backlash", {{"enabled", true}}}}}}, "f"), std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"effects", {{"delay", {{"dd", 0.1}}}}}}, "f"), std::invalid_argument);
  // The caller's "kind" is ignored.
  EXPECT_NO_THROW(PhysicsConfig::fromJson({{"kind", "physics"}}, "f"));
}

TEST(PhysicsConfigJson, BadValuesAreNamed) {
  try {
    PhysicsConfig::fromJson({{"payload", {{"mass_kg", "heavy"}}}}, "f");
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'mass_kg' must be a number"), std::string::npos) << e.what();
  }
  EXPECT_THROW(PhysicsConfig::fromJson({{"mode", "ideal"}}, "f"), std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"substeps", 2.5}}, "f"), std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"stroke", {{"enabled", 1}}}}, "f"), std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"payload", {{"mass_kg", -1.0}}}}, "f"), std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"seed", -3}}, "f"), std::invalid_argument);
  // Rig mode has its own pressure dynamics: pressure_lag is refused there, accepted in reference.
  EXPECT_THROW(PhysicsConfig::fromJson({{"effects", {{"pressure_lag", {{"enabled", true}}}}}}, "f"),
               std::invalid_argument);
  EXPECT_NO_THROW(
      PhysicsConfig::fromJson({{"mode", "reference"}, {"effects", {{"pressure_lag", {{"enabled", true}}}}}}, "f"));
  EXPECT_THROW(PhysicsConfig::fromJson(
                   {{"mode", "reference"},
                    {"effects", {{"mass_spring", {{"enabled", true}}}, {"force_loop", {{"enabled", true}}}}}},
                   "f"),
               std::invalid_argument);
  EXPECT_THROW(PhysicsConfig::fromJson({{"effects", {{"delay", {{"d", 5.0}}}}}}, "f"), std::invalid_argument);
}

TEST(PhysicsConfigJson, RoundTrip) {
  PhysicsConfig c = PhysicsConfig::fromJson(
      {{"mode", "reference"},
       {"Ts", 0.002},
       {"reference_substeps", 300},
       {"seed", 7},
       {"stroke", {{"enabled", false}, {"max_mm", 35.0}}},
       {"sensor", {{"noise_std_mm", 0.01}}},
       {"muscle", {{"braid_angle_deg", 24.0}}},
       {"reference", {{"k", 8.5}, {"gamma", 0.2}}},
       {"effects", {{"creep", {{"fraction", 0.1}}}, {"warm_up", {{"enabled", false}, {"tau", 30.0}}}}}},
      "f");
  EXPECT_EQ(c.mode, Mode::Reference);
  EXPECT_TRUE(c.effects.creep.enabled);
  EXPECT_FALSE(c.effects.warm_up.enabled);
  EXPECT_EQ(c.effects.warm_up.tau, 30.0);
  EXPECT_EQ(c.reference.k, 8.5);
  const nlohmann::json j = c.toJson();
  EXPECT_EQ(j.at("kind"), "physics");
  const PhysicsConfig d = PhysicsConfig::fromJson(j, "round trip");
  EXPECT_EQ(d.toJson(), j);
  EXPECT_EQ(d.Ts, 0.002);
  EXPECT_EQ(d.reference_substeps, 300);
  EXPECT_EQ(d.seed, 7u);
  EXPECT_FALSE(d.stroke_limits);
  EXPECT_EQ(d.stroke_max_mm, 35.0);
  EXPECT_EQ(d.muscle.braid_angle_deg, 24.0);
  EXPECT_EQ(d.effects.creep.fraction, 0.1);
  // The defaults round-trip too.
  const nlohmann::json def = PhysicsConfig::defaults().toJson();
  EXPECT_EQ(PhysicsConfig::fromJson(def, "d").toJson(), def);
}

#if PAMC_COUNT_ALLOCATIONS
TEST(PhysicsCycle, StepAndMeasureAllocateNothing) {
  // Counted once without the plant first: the counter sees a vector's allocation.
  {
    pamc::test::CountAllocations c;
    { std::vector<double> v(10); }
    ASSERT_EQ(c.count(), 1);
  }
  for (Mode m : {Mode::Rig, Mode::Reference}) {
    PhysicsConfig c = PhysicsConfig::defaults();
    c.mode = m;
    c.effects.delay.enabled = true;
    c.effects.delay.d = 0.0025;
    c.effects.creep.enabled = c.effects.warm_up.enabled = true;
    PhysicsPlant p(c);
    p.reset(0.0);
    double sink = 0.0;
    pamc::test::CountAllocations counter;
    for (int i = 0; i < 10000; ++i) {
      sink += p.step(2.0 * std::sin(i * 3e-3), 10.0);
      sink += p.measure() + p.pressure_bar();
    }
    EXPECT_EQ(counter.count(), 0) << (m == Mode::Rig ? "rig" : "reference");
    EXPECT_TRUE(std::isfinite(sink));
  }
}
#endif

// The project's PI gains (kp 0.1 V/mm, ki 3 V/(mm s): control::kDefaultGains, written out here because
// this test links no controller; and 1.3, the nodes' default before) with the integral clamped to the
// command range close a stable loop on the default rig: steps are reached and held without ringing, a
// slow sine is followed.
class PhysicsRigGains : public ::testing::TestWithParam<double> {};
TEST_P(PhysicsRigGains, ExistingPiGainsStabilise) {
  PhysicsPlant p(PhysicsConfig::defaults());
  const double kp = 0.1, ki = GetParam(), Ts = 1e-3;
  double integ = 0.0;
  p.reset(0.0);
  auto r_of = [](double t) {
    if (t < 3.0) return 20.0;
    if (t < 6.0) return 28.0;
    if (t < 9.0) return 12.0;
    return 20.0 + 5.0 * std::sin(2.0 * kPi * 0.2 * (t - 9.0));
  };
  double err_end_of_holds = 0.0, err_sine = 0.0;
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  for (int k = 0; k < 14000; ++k) {
    const double t = k * Ts;
    const double e = r_of(t) - p.measure();
    integ = std::clamp(integ + ki * Ts * e, -5.0, 5.0);
    const double y = p.step(kp * e + integ);
    const int hold = static_cast<int>(t / 3.0);
    if (hold < 3 && t - 3.0 * hold > 2.5) {  // the last half second of each hold
      lo[hold] = std::min(lo[hold], y);
      hi[hold] = std::max(hi[hold], y);
      err_end_of_holds = std::max(err_end_of_holds, std::fabs(r_of(t) - y));
    }
    if (t > 11.0) err_sine = std::max(err_sine, std::fabs(r_of(t) - y));
  }
  EXPECT_LT(err_end_of_holds, 0.1);
  for (int h = 0; h < 3; ++h) EXPECT_LT(hi[h] - lo[h], 0.05) << "hold " << h;
  EXPECT_LT(err_sine, 2.5);  // half the sine's amplitude: followed, with the PI's lag
}
INSTANTIATE_TEST_SUITE_P(PhysicsRig, PhysicsRigGains, ::testing::Values(3.0, 1.3));
