// Estimator and controller under bad data (docs/RELIABILITY.md, "Bad data in the estimator and
// controller"): NaN and infinite positions, 40 mm spikes of one or more samples, a stuck sensor, a valve
// that goes to a limit or stops responding for seconds - injected at random times into closed-loop runs
// of every controller on the plant emulator (cycle order and bus delay of the lockstep simulation).
//
// Checked in every cycle of every run: the command is finite and inside the valve's range; the PI
// integral is finite, inside the valve's range, held while the position is unusable and never moved
// further into a saturated limit (conditional integration); every non-finite position is reported as
// not used; for PI + AMC the UKF's covariance is symmetric and positive definite, every reset is
// reported and no run of rejected positions outlasts the gate's limit. After the faults: back to the
// fault-free run (same seed) within a bounded time. On clean data the gate never fires and changes no
// bit of the output. Then the filter alone, the windup after a valve saturation against a fault-free
// run, and the CANopen controller node on the in-process rig.
//
// `build/tests/pamc_tests --gtest_filter='BadData*'` prints the figures of docs/RELIABILITY.md.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "canopen/bus.hpp"
#include "canopen/node.hpp"
#include "control/controller.hpp"
#include "estimation/active_model.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"
#include "rig/virtual_rig.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"
#include "control/trajectory.hpp"

using namespace pamc;

namespace {

constexpr double kTs = 1e-3;
constexpr double kSpikeMm = 40.0;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kBandMm = 0.5;  // "back": within this of the fault-free run, and staying there

enum class Bad { NaN, PosInf, NegInf, Spike, Stuck, ValveLimit, ValveFrozen };
constexpr int kBadKinds = 7;

const char* badName(Bad b) {
  switch (b) {
    case Bad::NaN: return "NaN position, 1-500 samples";
    case Bad::PosInf: return "+inf position, 1-500 samples";
    case Bad::NegInf: return "-inf position, 1-500 samples";
    case Bad::Spike: return "spike +-40 mm, 1-31 samples";
    case Bad::Stuck: return "stuck sensor, 0.5-3 s";
    case Bad::ValveLimit: return "valve at -5 or +5 V, 1-5 s";
    case Bad::ValveFrozen: return "valve not responding, 1-5 s";
  }
  return "?";
}

// Time back to the fault-free run after the last fault ended, by fault kind [s]: the worst case of
// these runs with margin (ki = 0.15 is the slow case, PID + ESO the slowest: its observer's 60 s mode).
double backBound(Bad b) {
  switch (b) {
    case Bad::NaN:
    case Bad::PosInf:
    case Bad::NegInf: return 2.0;
    case Bad::Spike: return 4.0;
    case Bad::Stuck: return 6.0;
    case Bad::ValveLimit:
    case Bad::ValveFrozen: return 11.0;
  }
  return 11.0;
}

struct Fault {
  Bad kind = Bad::NaN;
  long k0 = 0, len = 1;  // cycles after the pre-roll
  double value = 0.0;    // spike height [mm] or valve command [V]
  long end() const { return k0 + len; }
};

struct Spec {
  control::Kind kind = control::Kind::PI;
  double ki = 0.15;
  bool full_model = false;  // AMC on the emulator's whole model (the rig's choice), not its Bouc-Wen core
  double gate_nis = -1.0;   // < 0: the default of ActiveModelSettings
  control::Trajectory traj = control::Trajectory::constant(20.0);
  long cycles = 8000;
  std::vector<Fault> faults;
  std::uint64_t plant_seed = 1;
};

long lastEnd(const Spec& s) {
  long e = 0;
  for (const auto& f : s.faults) e = std::max(e, f.end());
  return e;
}

// What the cycles of a set of runs showed.
struct Checks {
  long runs = 0, cycles = 0;
  long violations = 0;
  std::string first;  // the first violation, with its run and cycle
  long nonfinite_in = 0, nonfinite_flagged = 0;
  long outliers = 0;  // finite positions the AMC's gate rejected
  long resets = 0, resets_reported = 0;
  int longest_outlier_run = 0;
  double min_eig = kInf;  // smallest eigenvalue of the UKF's P seen
  double max_asym = 0.0;
  double max_abs_integral = 0.0;
  double max_abs_x3 = 0.0;
  double u_lo = kInf, u_hi = -kInf;

  void fail(const std::string& what, long run, long k) {
    if (violations++ == 0) first = what + " (run " + std::to_string(run) + ", cycle " + std::to_string(k) + ")";
  }
};

struct Trace {
  std::vector<double> yd, y_true, u, integral;
};

control::ControllerConfig controllerConfig(const Spec& s) {
  control::ControllerConfig c;
  c.ki = s.ki;
  // ki 0.15 is the paper's gain set as printed; its ESO is the printed one too. (The first-order ESO,
  // fitted with ki 1.3, comes back from a valve or a stuck-sensor fault with ki 0.15 more slowly than
  // backBound() allows: docs/RELIABILITY.md.)
  if (s.ki < 1.0) c.eso.order = 2;
  const auto truth = plant::PlantConfig::modelDefaults().truth;
  c.model = s.full_model ? truth : model::Model(truth.core());
  if (s.gate_nis >= 0.0) c.ukf.gate_nis = s.gate_nis;
  return c;
}

// One closed loop: pre-roll 1 s at the first setpoint, then `cycles` cycles with the faults. The
// position the controller sees at cycle k reflects the command of cycle k-3 (delay_cycles = 2), as in
// sim::runClosedLoop. With `checks`, every cycle after the pre-roll is checked.
Trace simulate(const Spec& s, Checks* checks = nullptr, long run = 0) {
  const auto cfg = controllerConfig(s);
  auto ctrl = control::makeController(s.kind, cfg);
  auto pc = plant::PlantConfig::modelDefaults();
  pc.seed = s.plant_seed;
  plant::Plant plant(pc);
  // The faults, injected through the loop's hooks: on the position the controller is given, and on
  // the command the valve applies.
  std::vector<double> stuck_at(s.faults.size(), 0.0);
  double y_last_read = NAN;
  sim::Lockstep::Hooks hooks;
  hooks.measurement = [&](long k, double y_read) {
    double y = y_read;
    for (size_t i = 0; i < s.faults.size(); ++i) {
      const Fault& f = s.faults[i];
      if (k == f.k0) stuck_at[i] = std::isnan(y_last_read) ? y_read : y_last_read;
      if (k < f.k0 || k >= f.end()) continue;
      switch (f.kind) {
        case Bad::NaN: y = std::numeric_limits<double>::quiet_NaN(); break;
        case Bad::PosInf: y = kInf; break;
        case Bad::NegInf: y = -kInf; break;
        case Bad::Spike: y += f.value; break;
        case Bad::Stuck: y = stuck_at[i]; break;
        default: break;
      }
    }
    y_last_read = y_read;
    return y;
  };
  double applied_prev = 0.0;
  hooks.valve = [&](long k, double applied) {
    for (const Fault& f : s.faults) {
      if (k < f.k0 || k >= f.end()) continue;
      if (f.kind == Bad::ValveFrozen) applied = applied_prev;
      if (f.kind == Bad::ValveLimit) applied = f.value;
    }
    applied_prev = applied;
    return applied;
  };
  sim::ClosedLoopRun cl;
  cl.reference = s.traj;
  cl.duration_s = static_cast<double>(s.cycles) * kTs;
  cl.preroll_s = 1.0;
  cl.delay_cycles = 2;
  sim::Lockstep loop(*ctrl, plant, cl, 0.0, hooks);
  loop.start();
  applied_prev = loop.lastApplied();

  Trace tr;
  for (auto* v : {&tr.yd, &tr.y_true, &tr.u, &tr.integral}) v->reserve(static_cast<size_t>(s.cycles));
  const auto* am = ctrl->activeModel();
  const int max_run = cfg.ukf.gate_max_rejects;
  unsigned resets_seen = am ? am->resets() : 0;
  double integ_prev = ctrl->integral();
  int outlier_run = 0;
  while (!loop.done()) {
    const long k = loop.cycle();
    const auto o = loop.step();
    const double y = loop.lastMeasurement();
    const double yd = loop.record().yd.back();
    tr.yd.push_back(yd);
    tr.y_true.push_back(plant.position());
    tr.u.push_back(o.u);
    tr.integral.push_back(ctrl->integral());

    if (!checks) continue;
    Checks& c = *checks;
    ++c.cycles;
    c.u_lo = std::min(c.u_lo, o.u);
    c.u_hi = std::max(c.u_hi, o.u);
    if (!std::isfinite(o.u) || o.u < cfg.u_min || o.u > cfg.u_max) c.fail("command outside the valve's range", run, k);
    if (!std::isfinite(o.y_hat)) c.fail("non-finite estimate", run, k);
    if (s.kind == control::Kind::OpenLoop) continue;  // it does not read the position
    const bool nonfinite = !std::isfinite(y);
    if (nonfinite) {
      ++c.nonfinite_in;
      if (o.measurement_rejected)
        ++c.nonfinite_flagged;
      else
        c.fail("non-finite position used without saying so", run, k);
    }
    const double integ = ctrl->integral();
    c.max_abs_integral = std::max(c.max_abs_integral, std::fabs(integ));
    if (!std::isfinite(integ) || integ < cfg.u_min || integ > cfg.u_max)
      c.fail("integral outside the valve's range", run, k);
    if (o.measurement_rejected && integ != integ_prev) c.fail("integral moved on an unusable position", run, k);
    if ((integ > integ_prev && o.saturated && o.u >= cfg.u_max) ||
        (integ < integ_prev && o.saturated && o.u <= cfg.u_min))
      c.fail("integral pushed further into a saturated limit (windup)", run, k);
    integ_prev = integ;
    if (s.kind == control::Kind::PidEso) {
      if (!std::isfinite(ctrl->disturbance())) c.fail("non-finite ESO state", run, k);
      c.max_abs_x3 = std::max(c.max_abs_x3, std::fabs(ctrl->disturbance()));
    }
    if (!am) continue;
    using PMat = estimation::ActiveModel::Filter::Mat;
    const PMat P = am->covariance();
    const double asym = (P - P.transpose()).cwiseAbs().maxCoeff();
    c.max_asym = std::max(c.max_asym, asym);
    const Eigen::LLT<PMat> llt(P);
    const Eigen::SelfAdjointEigenSolver<PMat> es(P, Eigen::EigenvaluesOnly);
    const double eig = es.eigenvalues().minCoeff();
    c.min_eig = std::min(c.min_eig, eig);
    if (!P.allFinite() || asym != 0.0 || llt.info() != Eigen::Success || !(eig > 0.0))
      c.fail("UKF covariance not symmetric positive definite", run, k);
    const unsigned r = am->resets();
    if (r != resets_seen) {
      c.resets += r - resets_seen;
      if (o.estimator_reset)
        ++c.resets_reported;
      else
        c.fail("UKF reset without saying so", run, k);
    } else if (o.estimator_reset) {
      c.fail("estimator_reset reported without a reset", run, k);
    }
    resets_seen = r;
    if (!nonfinite && o.measurement_rejected) {
      ++c.outliers;
      c.longest_outlier_run = std::max(c.longest_outlier_run, ++outlier_run);
      if (outlier_run > max_run) c.fail("positions rejected beyond the gate's limit without a reset", run, k);
    } else if (!o.measurement_rejected) {
      outlier_run = 0;
    }
  }
  if (checks) ++checks->runs;
  return tr;
}

// After the faults: how far the faulted run strays from the fault-free one, and when it is back.
struct Recovery {
  double peak = 0;          // largest |y - y_ref| from the end of the last fault on [mm]
  double overshoot = 0;     // largest deviation on the other side of the reference than at that end [mm]
  double back_after_s = 0;  // from the end of the last fault until |y - y_ref| stays within the band
  bool back = true;         // within the band for at least the last 0.5 s
};

Recovery recovery(const Trace& f, const Trace& ref, long from) {
  Recovery r;
  const size_t n = f.y_true.size();
  const size_t i0 = static_cast<size_t>(std::max(from, 0L));
  if (i0 >= n) return r;
  const double side = f.y_true[i0] >= ref.y_true[i0] ? 1.0 : -1.0;
  size_t last_out = i0;
  bool out = false;
  for (size_t i = i0; i < n; ++i) {
    const double d = f.y_true[i] - ref.y_true[i];
    r.peak = std::max(r.peak, std::fabs(d));
    r.overshoot = std::max(r.overshoot, -side * d);
    if (std::fabs(d) > kBandMm) last_out = i, out = true;
  }
  r.back_after_s = out ? static_cast<double>(last_out + 1 - i0) * kTs : 0.0;
  r.back = !out || last_out + 500 < n;
  return r;
}

// A random run: gains, trajectory, model, and `n_faults` faults of the given kind (or of random kinds
// with mixed = true) at random times with random lengths.
Spec randomSpec(std::uint64_t seed, control::Kind kind, Bad bad, int n_faults, bool mixed, int whole_model = -1) {
  std::mt19937_64 rng(seed);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  Spec s;
  s.kind = kind;
  s.ki = pick(2) ? 1.5 : 0.15;
  s.full_model = kind == control::Kind::PiAmc && (whole_model >= 0 ? whole_model == 1 : pick(4) == 0);
  s.plant_seed = seed;
  const double lo = uni(5, 15), hi = uni(20, 30);
  switch (pick(4)) {
    case 0: s.traj = control::Trajectory::sine(uni(0.05, 0.3), 0.5 * (hi - lo), 0.5 * (hi + lo)); break;
    case 1: s.traj = control::Trajectory::triangle(uni(0.05, 0.2), lo, hi); break;
    case 2: s.traj = control::Trajectory::square(uni(0.05, 0.2), lo, lo + uni(2, 8)); break;
    default: s.traj = control::Trajectory::constant(uni(lo, hi)); break;
  }
  for (int i = 0; i < n_faults; ++i) {
    Fault f;
    f.kind = mixed ? static_cast<Bad>(pick(kBadKinds)) : bad;
    f.k0 = static_cast<long>(uni(0.5, 4.0) / kTs);
    switch (f.kind) {
      case Bad::NaN:
      case Bad::PosInf:
      case Bad::NegInf: f.len = pick(2) ? 1 : 1 + pick(500); break;
      case Bad::Spike:
        f.len = pick(2) ? 1 : 2 + pick(30);
        f.value = pick(2) ? kSpikeMm : -kSpikeMm;
        break;
      case Bad::Stuck: f.len = static_cast<long>(uni(0.5, 3.0) / kTs); break;
      case Bad::ValveLimit:
        f.len = static_cast<long>(uni(1.0, 5.0) / kTs);
        f.value = pick(2) ? 5.0 : -5.0;
        break;
      case Bad::ValveFrozen: f.len = static_cast<long>(uni(1.0, 5.0) / kTs); break;
    }
    s.faults.push_back(f);
  }
  s.cycles = lastEnd(s) + static_cast<long>(12.0 / kTs);
  return s;
}

const control::Kind kAllKinds[] = {control::Kind::OpenLoop, control::Kind::PI, control::Kind::PidEso,
                                   control::Kind::PiAmc};

// Worst recovery of a set of runs (by controller).
struct Worst {
  double back_s = 0, peak = 0, overshoot = 0;
  long runs = 0;
  void add(const Recovery& r) {
    ++runs;
    back_s = std::max(back_s, r.back_after_s);
    peak = std::max(peak, r.peak);
    overshoot = std::max(overshoot, r.overshoot);
  }
};

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[96];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

}  // namespace

// ------------------------------------------------------------------ property tests over random runs

// Every fault kind on every controller: 12 seeded runs per pair (one or two faults of that kind, gains
// ki 0.15 or 1.5, sine / triangle / square / constant setpoints; for PI + AMC every fourth run on the
// emulator's whole model, whose mass-spring output the UKF cannot follow), each against its fault-free
// twin.
TEST(BadDataProperty, EveryFaultKindOnEveryControllerInEveryCycle) {
  constexpr int kRunsPerPair = 12;
  Checks total, clean;
  std::string table =
      "| fault | runs | cycles | unusable positions reported | AMC: outliers rejected / resets (reported) | "
      "back to the fault-free run, worst: PI / ESO / AMC [s] | worst deviation after: PI / ESO / AMC [mm] | "
      "AMC on the emulator's whole model: back [s] / deviation [mm] |\n|---|---|---|---|---|---|---|---|\n";
  long run_id = 0;
  for (int b = 0; b < kBadKinds; ++b) {
    const Bad bad = static_cast<Bad>(b);
    Checks kc;
    Worst w[4], w_full;
    for (const auto kind : kAllKinds) {
      for (int i = 0; i < kRunsPerPair; ++i, ++run_id) {
        const Spec s =
            randomSpec(0xBAD0000 + static_cast<std::uint64_t>(run_id), kind, bad, 1 + i % 2, false, i % 4 == 3);
        Spec ref = s;
        ref.faults.clear();
        const Trace f = simulate(s, &kc, run_id);
        const Trace r = simulate(ref, &clean, run_id);
        if (kind == control::Kind::OpenLoop) continue;  // no feedback: it does not come back to anything
        const auto rec = recovery(f, r, lastEnd(s));
        (s.full_model ? w_full : w[static_cast<int>(kind)]).add(rec);
        SCOPED_TRACE(std::string(control::toString(kind)) + ", " + badName(bad) + ", run " + std::to_string(run_id) +
                     ", ki " + fmt("%g", s.ki) + (s.full_model ? ", whole model" : "") + ", " + s.traj.describe());
        EXPECT_TRUE(rec.back) << "not back within " << kBandMm << " mm of the fault-free run";
        if (!s.full_model) {
          EXPECT_LE(rec.back_after_s, backBound(bad));
        }
      }
    }
    EXPECT_EQ(kc.violations, 0) << badName(bad) << ": " << kc.first;
    EXPECT_EQ(kc.nonfinite_flagged, kc.nonfinite_in);
    EXPECT_EQ(kc.resets_reported, kc.resets);
    if (bad == Bad::Spike) {
      EXPECT_GT(kc.outliers, 0) << "the AMC's gate never rejected a 40 mm spike";
    }
    auto three = [&](double Worst::*m, const char* f) { return fmt(f, w[1].*m, w[2].*m, w[3].*m); };
    table += std::string("| ") + badName(bad) + " | " + std::to_string(kc.runs) + " | " + std::to_string(kc.cycles) +
             " | " + std::to_string(kc.nonfinite_flagged) + " of " + std::to_string(kc.nonfinite_in) + " | " +
             std::to_string(kc.outliers) + " / " + std::to_string(kc.resets) + " (" +
             std::to_string(kc.resets_reported) + ") | " + three(&Worst::back_s, "%.2f / %.2f / %.2f") + " | " +
             three(&Worst::peak, "%.1f / %.1f / %.1f") + " | " +
             (w_full.runs ? fmt("%.0f runs: %.2f / %.1f", static_cast<double>(w_full.runs), w_full.back_s, w_full.peak)
                          : "-") +
             " |\n";
    total.runs += kc.runs;
    total.cycles += kc.cycles;
    total.min_eig = std::min(total.min_eig, kc.min_eig);
    total.max_abs_integral = std::max(total.max_abs_integral, kc.max_abs_integral);
    total.max_abs_x3 = std::max(total.max_abs_x3, kc.max_abs_x3);
    total.u_lo = std::min(total.u_lo, kc.u_lo);
    total.u_hi = std::max(total.u_hi, kc.u_hi);
    total.longest_outlier_run = std::max(total.longest_outlier_run, kc.longest_outlier_run);
  }
  // The fault-free twins: every check holds, the gate never fires, the filter never resets.
  EXPECT_EQ(clean.violations, 0) << clean.first;
  EXPECT_EQ(clean.outliers, 0);
  EXPECT_EQ(clean.resets, 0);
  std::printf("%s", table.c_str());
  std::printf(
      "faulted runs %ld, cycles checked %ld (fault-free twins: %ld runs, %ld cycles, %ld gate rejections, %ld resets); "
      "command in [%.3f, %.3f] V; |integral| <= %.3f V; |ESO x3| <= %.2f; UKF P: smallest eigenvalue %.3g; "
      "longest run of rejected positions %d\n",
      total.runs, total.cycles, clean.runs, clean.cycles, clean.outliers, clean.resets, total.u_lo, total.u_hi,
      total.max_abs_integral, total.max_abs_x3, total.min_eig, total.longest_outlier_run);
  RecordProperty("runs", static_cast<int>(total.runs));
  RecordProperty("cycles", std::to_string(total.cycles));
}

// Two to four faults of mixed kinds in one run, overlapping at random.
TEST(BadDataProperty, MixedFaultsInOneRun) {
  Checks c, clean;
  Worst w;
  long run_id = 0;
  for (const auto kind : kAllKinds) {
    for (int i = 0; i < 20; ++i, ++run_id) {
      const Spec s = randomSpec(0xC0FFEE + static_cast<std::uint64_t>(run_id), kind, Bad::NaN, 2 + i % 3, true);
      Spec ref = s;
      ref.faults.clear();
      const Trace f = simulate(s, &c, run_id);
      const Trace r = simulate(ref, &clean, run_id);
      if (kind == control::Kind::OpenLoop) continue;
      const auto rec = recovery(f, r, lastEnd(s));
      double bound = 0;
      for (const auto& x : s.faults) bound = std::max(bound, backBound(x.kind));
      SCOPED_TRACE(std::string(control::toString(kind)) + ", run " + std::to_string(run_id) + ", ki " +
                   fmt("%g", s.ki) + (s.full_model ? ", whole model" : "") + ", " + s.traj.describe());
      EXPECT_TRUE(rec.back);
      if (!s.full_model) {
        EXPECT_LE(rec.back_after_s, bound);
        w.add(rec);
      }
    }
  }
  EXPECT_EQ(c.violations, 0) << c.first;
  EXPECT_EQ(clean.violations, 0) << clean.first;
  EXPECT_EQ(clean.outliers, 0);
  EXPECT_EQ(c.nonfinite_flagged, c.nonfinite_in);
  EXPECT_EQ(c.resets_reported, c.resets);
  std::printf(
      "mixed: %ld runs, %ld cycles checked, %ld unusable positions reported of %ld, %ld outliers, %ld resets "
      "(%ld reported); worst back %.2f s, deviation %.1f mm\n",
      c.runs, c.cycles, c.nonfinite_flagged, c.nonfinite_in, c.outliers, c.resets, c.resets_reported, w.back_s, w.peak);
}

// The gate changes nothing on clean data: the same commands bit for bit with and without it, on the
// trajectories of Table 2 and on setpoint steps (where the model moves at once and the muscle lags).
TEST(BadDataProperty, CleanDataNeverReachesTheGate) {
  const control::Trajectory trajs[] = {
      control::Trajectory::sine(0.05, 14.9, 15.0),    control::Trajectory::sine(0.1, 14.9, 15.0),
      control::Trajectory::triangle(0.05, 0.2, 30.0), control::Trajectory::square(0.1, 10.0, 25.0),
      control::Trajectory::sawtooth(0.1, 10.0, 25.0), control::Trajectory::square(0.1, 5.0, 35.0)};
  double max_nis = 0.0;
  for (const auto& traj : trajs) {
    for (double ki : {0.15, 1.5}) {
      Spec s;
      s.kind = control::Kind::PiAmc;
      s.ki = ki;
      s.traj = traj;
      s.cycles = 20000;
      Checks c;
      const Trace gated = simulate(s, &c);
      s.gate_nis = 0.0;
      const Trace plain = simulate(s);
      EXPECT_EQ(gated.u, plain.u) << traj.describe() << ", ki " << ki;
      EXPECT_EQ(c.outliers, 0);
      EXPECT_EQ(c.violations, 0) << c.first;
      // The largest NIS on this trajectory, from a third run that watches the filter.
      s.gate_nis = -1.0;
      auto ctrl = control::makeController(s.kind, controllerConfig(s));
      plant::Plant p(plant::PlantConfig::modelDefaults());
      p.reset(0.0);
      ctrl->activate(0.0, p.measure());
      std::array<double, 3> pipe{0, 0, 0};
      for (long k = 0; k < 20000; ++k) {
        const double t = k * kTs;
        const auto o = ctrl->update(traj.at(t), traj.at(t + kTs), p.measure());
        if (k > 1000) max_nis = std::max(max_nis, ctrl->activeModel()->gateStatistic());
        pipe = {o.u, pipe[0], pipe[1]};
        p.step(pipe[2]);
      }
    }
  }
  EXPECT_LT(max_nis, 0.1 * estimation::ActiveModelSettings{}.gate_nis);
  std::printf("clean data: largest gate statistic %.3g (gate %.0f)\n", max_nis,
              estimation::ActiveModelSettings{}.gate_nis);
}

// ------------------------------------------------------------------------------- the filter alone

namespace {
// The AMC's estimator on the emulator's Bouc-Wen core, fed by the emulator under a slow sine command.
// The emulator's pressure is made fast (40 ms) so that the core alone predicts it within 0.1 mm over a
// 20-sample spike: the test is about the gate, not about the model's error.
plant::PlantConfig fastPressure() {
  auto c = plant::PlantConfig::modelDefaults();
  c.truth.setEffectParam("pressure_lag", "tau", 0.04);
  return c;
}
struct FilterBench {
  estimation::ActiveModel am;
  plant::Plant plant{fastPressure()};
  long k = 0;
  double y_true = 0.0;
  FilterBench() {
    am.configure(model::Model(plant::PlantConfig::modelDefaults().truth.core()), estimation::ActiveModelSettings{},
                 kTs);
    plant.reset(0.0);
    am.reset(0.0);
  }
  // One sample; `edit` turns the measurement into bad data.
  estimation::ActiveModelStep step(const std::function<double(double)>& edit = nullptr) {
    const double u = 2.0 * std::sin(2 * M_PI * 0.2 * static_cast<double>(k++) * kTs);
    y_true = plant.step(u);
    const double y = plant.measure();
    return am.update(u, edit ? edit(y) : y);
  }
  bool spd() const {
    using PMat = estimation::ActiveModel::Filter::Mat;
    const PMat& P = am.covariance();
    const Eigen::SelfAdjointEigenSolver<PMat> es(P, Eigen::EigenvaluesOnly);
    return P.allFinite() && P == P.transpose() && Eigen::LLT<PMat>(P).info() == Eigen::Success &&
           es.eigenvalues().minCoeff() > 0.0;
  }
};
}  // namespace

TEST(BadDataUkf, SpikesAreRejectedByTheGateAndTheCovarianceIsHeld) {
  FilterBench b;
  double clean_nis = 0;
  for (int i = 0; i < 2000; ++i) clean_nis = std::max(clean_nis, b.step().nis);
  EXPECT_LT(clean_nis, 1.0);  // the first samples after the reset included
  for (double spike : {kSpikeMm, -kSpikeMm}) {
    for (int len : {1, 10, 20}) {
      for (int i = 0; i < len; ++i) {
        const estimation::ActiveModel::Filter::Mat P_before = b.am.covariance();
        const auto st = b.step([&](double y) { return y + spike; });
        EXPECT_EQ(st.status, estimation::UkfStatus::OutlierRejected) << spike << " mm, sample " << i << " of " << len;
        EXPECT_TRUE(st.rejected);
        EXPECT_GT(st.nis_gate, estimation::ActiveModelSettings{}.gate_nis);
        EXPECT_LT(std::fabs(st.y_post - b.y_true), 0.1);  // the model's prediction, not the spike
        EXPECT_EQ(b.am.covariance(), P_before);           // held: the run is judged against the same spread
        EXPECT_TRUE(b.spd());
      }
      const auto st = b.step();
      EXPECT_EQ(st.status, estimation::UkfStatus::Ok) << "the position after the spike is used";
      EXPECT_LT(std::fabs(st.y_post - b.y_true), 0.05);
      for (int i = 0; i < 200; ++i) b.step();
    }
  }
  EXPECT_EQ(b.am.resets(), 0u);
  EXPECT_EQ(b.am.outliers(), 2u * (1 + 10 + 20));
}

TEST(BadDataUkf, AJumpThatStaysIsTakenAfterTheLimitWithAReset) {
  FilterBench b;
  for (int i = 0; i < 2000; ++i) b.step();
  const int limit = estimation::ActiveModelSettings{}.gate_max_rejects;
  auto jump = [](double y) { return y + kSpikeMm; };
  for (int i = 0; i < limit; ++i) EXPECT_EQ(b.step(jump).status, estimation::UkfStatus::OutlierRejected) << i;
  const auto st = b.step(jump);
  EXPECT_EQ(st.status, estimation::UkfStatus::Reset) << "the filter must start over and say so";
  EXPECT_FALSE(st.rejected);
  EXPECT_EQ(b.am.resets(), 1u);
  EXPECT_LT(std::fabs(st.y_post - (b.y_true + kSpikeMm)), 1.0);  // on the new level
  EXPECT_TRUE(b.spd());
  for (int i = 0; i < 100; ++i) EXPECT_FALSE(b.step(jump).rejected);
  // The way back is not gated (the gate re-learns after a restart): no second reset.
  for (int i = 0; i < 100; ++i) {
    const auto s2 = b.step();
    EXPECT_FALSE(s2.rejected);
    EXPECT_NE(s2.status, estimation::UkfStatus::Reset);
  }
  EXPECT_EQ(b.am.resets(), 1u);
}

TEST(BadDataUkf, NonFinitePositionsAreRejectedAndTheSpreadGrows) {
  FilterBench b;
  for (int i = 0; i < 2000; ++i) b.step();
  double p_prev = b.am.covariance()(0, 0);
  for (int i = 0; i < 500; ++i) {
    const double bad = i % 3 == 0 ? std::numeric_limits<double>::quiet_NaN() : (i % 3 == 1 ? kInf : -kInf);
    const auto st = b.step([&](double) { return bad; });
    EXPECT_EQ(st.status, estimation::UkfStatus::MeasurementRejected) << i;
    EXPECT_TRUE(st.rejected);
    EXPECT_TRUE(std::isfinite(st.y_post));
    EXPECT_TRUE(b.spd());
    EXPECT_GT(b.am.covariance()(0, 0), p_prev);  // no measurement: the filter knows less every sample
    p_prev = b.am.covariance()(0, 0);
  }
  const auto st = b.step();
  EXPECT_EQ(st.status, estimation::UkfStatus::Ok);
  EXPECT_LT(std::fabs(st.y_post - b.y_true), 0.05);
  EXPECT_EQ(b.am.resets(), 0u);
  // A non-finite command does not reach the model's states either.
  EXPECT_TRUE(std::isfinite(b.am.update(std::numeric_limits<double>::quiet_NaN(), b.plant.measure()).y_post));
  EXPECT_TRUE(b.spd());
}

TEST(BadDataUkf, AResetIsNeverHiddenBehindARejection) {
  using estimation::UkfStatus;
  using estimation::worstOf;
  EXPECT_EQ(worstOf(UkfStatus::Reset, UkfStatus::MeasurementRejected), UkfStatus::Reset);
  EXPECT_EQ(worstOf(UkfStatus::MeasurementRejected, UkfStatus::Reset), UkfStatus::Reset);
  EXPECT_EQ(worstOf(UkfStatus::Reset, UkfStatus::OutlierRejected), UkfStatus::Reset);
  EXPECT_EQ(worstOf(UkfStatus::CovarianceRepaired, UkfStatus::MeasurementRejected), UkfStatus::MeasurementRejected);
  EXPECT_EQ(worstOf(UkfStatus::Ok, UkfStatus::CovarianceRepaired), UkfStatus::CovarianceRepaired);
  // In the filter: an indefinite P repaired while drawing the sigma points, then a NaN measurement.
  estimation::Ukf<2, 1> f;
  Eigen::Matrix2d bad;
  bad << 1.0, 2.0, 2.0, 1.0;
  f.reset(Eigen::Vector2d(0, 0), bad);
  const auto st = f.update([](const Eigen::Vector2d& x) { return Eigen::Matrix<double, 1, 1>(x(0)); },
                           Eigen::Matrix<double, 1, 1>(NAN), Eigen::Matrix<double, 1, 1>(1e-3));
  EXPECT_EQ(st, UkfStatus::MeasurementRejected);
  EXPECT_EQ(Eigen::LLT<Eigen::Matrix2d>(f.P()).info(), Eigen::Success);
}

// ------------------------------------------------------------------- windup after a valve saturation

namespace {
struct WindupCase {
  control::Kind kind;
  double ki;
  double back_bound_s;  // back to the fault-free run after the valve returns (worst seen, with margin)
};
}  // namespace

// The valve vents (-5 V) for 3 s while the setpoint stays at 20 mm: the controller's output rises into
// its upper limit, where conditional integration stops the integral - below the value that alone would
// saturate the output, not at the clamp. Then the valve returns: the muscle overshoots while the
// integral unwinds, and the loop is back at the fault-free run within a bounded time.
TEST(BadDataWindup, ValveVentedForThreeSecondsIntegralStopsAtTheSaturation) {
  const WindupCase cases[] = {{control::Kind::PI, 0.15, 8.0},     {control::Kind::PI, 1.5, 3.0},
                              {control::Kind::PidEso, 0.15, 9.0}, {control::Kind::PidEso, 1.5, 3.0},
                              {control::Kind::PiAmc, 0.15, 8.0},  {control::Kind::PiAmc, 1.5, 3.0}};
  for (const auto& wc : cases) {
    Spec s;
    s.kind = wc.kind;
    s.ki = wc.ki;
    s.traj = control::Trajectory::constant(20.0);
    s.faults = {Fault{Bad::ValveLimit, 2000, 3000, -5.0}};
    s.cycles = 20000;
    Spec ref = s;
    ref.faults.clear();
    Checks c;
    const Trace f = simulate(s, &c), r = simulate(ref);
    SCOPED_TRACE(std::string(control::toString(wc.kind)) + ", ki " + fmt("%g", wc.ki));
    EXPECT_EQ(c.violations, 0) << c.first;
    const size_t end = 5000;
    double i_max = -kInf;
    for (size_t k = 2000; k < end; ++k) i_max = std::max(i_max, f.integral[k]);
    // The output saturated at +5 V during the fault, and the integral stopped well below the clamp
    // (without conditional integration it runs to 5 V).
    EXPECT_GT(*std::max_element(f.u.begin() + 2000, f.u.begin() + end), 4.95);
    // The first-order ESO splits the holding command: the PI part holds y / eso_gain, the compensation
    // the rest, so its integral may meet its own clamp while the sum is not saturated; for it the
    // recovery below is the check.
    if (controllerConfig(s).eso.order != 1 || wc.kind != control::Kind::PidEso) {
      EXPECT_LT(i_max, 4.5);
    }
    const auto rec = recovery(f, r, static_cast<long>(end));
    EXPECT_TRUE(rec.back);
    EXPECT_LE(rec.back_after_s, wc.back_bound_s);
    std::printf(
        "windup %-4s ki %.2f: integral during the fault up to %.2f V (fault-free %.2f V); after: overshoot %.1f mm, "
        "back within %.1f mm after %.2f s\n",
        control::toString(wc.kind), wc.ki, i_max, r.integral[end - 1], rec.overshoot, kBandMm, rec.back_after_s);
  }
}

// --------------------------------------------------------------------- the CANopen controller node

namespace {
const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od/";

struct NodeRun {
  std::vector<nodes::CycleRecord> recs;
  std::vector<std::uint16_t> emcy;
  std::uint64_t faults = 0, recoveries = 0;
  nodes::Fault final_fault = nodes::Fault::None;
  double maxStep(double t0, double t1) const {  // largest |u_k - u_k-1| with t in [t0, t1)
    double m = 0;
    for (size_t i = 1; i < recs.size(); ++i)
      if (recs[i].t >= t0 && recs[i].t < t1) m = std::max(m, std::fabs(recs[i].u - recs[i - 1].u));
    return m;
  }
  bool sent(std::uint16_t code) const { return std::find(emcy.begin(), emcy.end(), code) != emcy.end(); }
};

// Controller, sensor and valve nodes on the in-process bus (1 ms SYNC, 0.2 Hz sine 10-20 mm, kp 0.1,
// ki 1.5, kc 0.06 as in the fault rig when these runs were measured, 2 s pre-roll); `edit` tampers with
// the position PDOs.
NodeRun runNode(control::Kind kind, bool whole_model, const std::function<void(long, std::int32_t&)>& edit,
                double duration_s = 6.0) {
  nodes::ControllerNodeConfig c;
  c.eds_path = kOd + "controller.eds";
  c.kind = static_cast<int>(kind);
  c.gains_from_config = true;
  c.ctrl.kp = 0.1;
  c.ctrl.ki = 1.5;
  c.ctrl.kc = 0.06;
  const auto truth = plant::PlantConfig::modelDefaults().truth;
  c.ctrl.model = whole_model ? truth : model::Model(truth.core());
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::sine(0.2, 5.0, 15.0);
  c.preroll_s = 2.0;
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "sensor.eds";
  e.valve_eds = kOd + "valve.eds";
  // The position PDOs (TPDO1 of node 2, INTEGER32 in 0.001 mm) on their way: the n-th since start
  // goes through `edit`.
  long n = 0;
  auto tamper = [&n, &edit](canopen::Frame& g) {
    if (g.id == 0x182 && g.len == 4 && !g.error() && !g.remote()) {
      auto v = static_cast<std::int32_t>(canopen::getU32(g.data));
      if (edit) edit(n, v);
      ++n;
      canopen::putU32(g.data, static_cast<std::uint32_t>(v));
    }
    return true;
  };
  rig::VirtualRig rig(c, e, 0, tamper);
  NodeRun r;
  rig.addTap([&r](const canopen::Frame& f, canopen::TimeUs) {
    if (f.id == 0x81 && f.len == 8 && !f.error()) r.emcy.push_back(canopen::getU16(f.data));
  });
  rig.start();
  auto* ctrl = &rig.controller();
  while (ctrl->runTime() < duration_s && rig.now() < static_cast<canopen::TimeUs>((duration_s + 40) * 1e6)) rig.step();
  rig.step(0);
  r.recs = std::move(rig.records());
  r.faults = ctrl->faultsRaised();
  r.recoveries = ctrl->faultCounters().recoveries;
  r.final_fault = ctrl->fault();
  return r;
}

// Position PDO index of trajectory time t (the first PDO starts the node; the pre-roll follows).
long pdoAt(double t) { return static_cast<long>(std::lround((2.0 + t) / kTs)); }
}  // namespace

// One position PDO 40 mm off, 3 s into the trajectory. PI + AMC on the Bouc-Wen core: the UKF's gate
// rejects it, the PI holds the last position - no fault, no step in the command. PI has no model to
// judge the sample by: the 40 mm error reaches the valve for one cycle (kp * 40 mm = 4 V), no fault.
TEST(BadDataNode, A40mmSpikeInThePositionPdo) {
  const long at = pdoAt(3.0);
  auto spike = [at](long n, std::int32_t& v) {
    if (n == at) v += 40000;
  };
  const NodeRun amc = runNode(control::Kind::PiAmc, false, spike);
  const NodeRun base = runNode(control::Kind::PiAmc, false, nullptr);
  EXPECT_EQ(amc.faults, 0u);
  EXPECT_TRUE(amc.emcy.empty());
  EXPECT_LE(amc.maxStep(2.9, 3.5), 2.0 * base.maxStep(2.9, 3.5) + 0.01);
  const NodeRun pi = runNode(control::Kind::PI, false, spike);
  EXPECT_EQ(pi.faults, 0u);
  EXPECT_GT(pi.maxStep(2.9, 3.5), 3.0);
  const NodeRun whole = runNode(control::Kind::PiAmc, true, spike);
  std::printf(
      "node, one PDO +40 mm: largest command step around it: PI + AMC (Bouc-Wen core) %.4f V (no spike %.4f V), "
      "PI %.3f V, PI + AMC on the whole emulator model %.3f V; faults %llu / %llu / %llu\n",
      amc.maxStep(2.9, 3.5), base.maxStep(2.9, 3.5), pi.maxStep(2.9, 3.5), whole.maxStep(2.9, 3.5),
      static_cast<unsigned long long>(amc.faults), static_cast<unsigned long long>(pi.faults),
      static_cast<unsigned long long>(whole.faults));
}

// The position jumps by 40 mm for 200 ms (a sensor that re-zeroed, a loose magnet). The UKF rejects
// gate_max_rejects positions, then takes the new level and resets: the node raises its estimator fault
// (EMCY 0x6100), the valve goes to its safe value, and control resumes after the jump, EMCY reset.
TEST(BadDataNode, AJumpThatStaysResetsTheUkfAndRaisesTheEstimatorFault) {
  const long at = pdoAt(3.0);
  const NodeRun r = runNode(control::Kind::PiAmc, false, [at](long n, std::int32_t& v) {
    if (n >= at && n < at + 200) v += 40000;
  });
  EXPECT_TRUE(r.sent(0x6100)) << "no EMCY 0x6100 after the UKF reset";
  EXPECT_TRUE(r.sent(0x0000)) << "no EMCY reset after recovery";
  EXPECT_GE(r.faults, 1u);
  EXPECT_GE(r.recoveries, 1u);
  EXPECT_EQ(r.final_fault, nodes::Fault::None);
  // The first reaction: the gate's limit after the jump (plus the cycle the PDO takes).
  double t_fault = -1;
  for (const auto& c : r.recs)
    if (c.fault == static_cast<std::uint8_t>(nodes::Fault::Estimator)) {
      t_fault = c.t;
      break;
    }
  const int limit = estimation::ActiveModelSettings{}.gate_max_rejects;
  EXPECT_GE(t_fault, 3.0);
  EXPECT_LE(t_fault, 3.0 + (limit + 3) * kTs);
  std::printf("node, position +40 mm for 200 ms: estimator fault %.0f cycles after the jump, EMCY:",
              (t_fault - 3.0) / kTs);
  for (auto e : r.emcy) std::printf(" 0x%04x", e);
  std::printf("; recoveries %llu\n", static_cast<unsigned long long>(r.recoveries));
}

// A position far outside the sensor's measuring range (0-100 mm, its 0x6002; the controller's 0x2022:01):
// INT32_MAX counts, 2147 m. The node does not hand it to the controller (NaN: the last usable position is
// held, the integral too, no step); up to 0x2021 = 3 in a row are ridden through, a fourth is a fault:
// EMCY 0x7310, safe state, back when the positions are.
TEST(BadDataNode, APositionOutsideTheMeasuringRange) {
  const long at = pdoAt(3.0);
  auto far = [at](int n_bad) {
    return [at, n_bad](long n, std::int32_t& v) {
      if (n >= at && n < at + n_bad) v = std::numeric_limits<std::int32_t>::max();
    };
  };
  const NodeRun base = runNode(control::Kind::PI, false, nullptr);
  for (auto kind : {control::Kind::PI, control::Kind::PiAmc}) {
    SCOPED_TRACE(control::toString(kind));
    const NodeRun three = runNode(kind, false, far(3));
    EXPECT_EQ(three.faults, 0u);
    EXPECT_TRUE(three.emcy.empty());
    EXPECT_LE(three.maxStep(2.9, 3.5), 2.0 * base.maxStep(2.9, 3.5) + 0.01);  // PI: was 4 V a cycle, to -5 V
    const NodeRun five = runNode(kind, false, far(5));
    EXPECT_GE(five.faults, 1u);
    EXPECT_TRUE(five.sent(canopen::kEmcySensorRange)) << "no EMCY 0x7310";
    EXPECT_TRUE(five.sent(0x0000)) << "no EMCY reset after recovery";
    EXPECT_EQ(five.final_fault, nodes::Fault::None);
    double t_fault = -1;
    for (const auto& c : five.recs)
      if (c.fault == static_cast<std::uint8_t>(nodes::Fault::PositionRange)) {
        t_fault = c.t;
        break;
      }
    EXPECT_GE(t_fault, 3.0);
    EXPECT_LE(t_fault, 3.0 + 6 * kTs);  // the fourth out-of-range position (plus the PDO's cycle)
    std::printf(
        "node (%s), positions at INT32_MAX: 3 in a row ridden through (largest step %.4f V); 5 in a row: "
        "fault %.0f cycles after the first, EMCY 0x7310, recovered %llu\n",
        control::toString(kind), three.maxStep(2.9, 3.5), (t_fault - 3.0) / kTs,
        static_cast<unsigned long long>(five.recoveries));
  }
}

// A stuck sensor: the position PDO repeats the value it had 3 s into the run, for 2 s. The PI's error
// grows, its command moves, the muscle moves - the position does not: after 0x2022:02 = 0.25 s with the
// command 0x2022:03 = 1 V or more away from where it was, the node raises its stuck-sensor fault (EMCY
// 0x7300), the valve goes safe; when the sensor moves again the run recovers. Without the fault-free
// twin ever raising it.
TEST(BadDataNode, AStuckSensorIsDetectedWhenTheCommandMovesAndThePositionDoesNot) {
  const long at = pdoAt(3.0);
  for (auto kind : {control::Kind::PI, control::Kind::PiAmc}) {
    SCOPED_TRACE(control::toString(kind));
    std::int32_t frozen = 0;
    const NodeRun r = runNode(
        kind, false,
        [at, &frozen](long n, std::int32_t& v) {
          if (n == at) frozen = v;
          if (n >= at && n < at + 2000) v = frozen;
        },
        8.0);
    EXPECT_TRUE(r.sent(canopen::kEmcySensor)) << "no EMCY 0x7300";
    EXPECT_TRUE(r.sent(0x0000)) << "no EMCY reset after recovery";
    EXPECT_GE(r.recoveries, 1u);
    EXPECT_EQ(r.final_fault, nodes::Fault::None);
    double t_fault = -1, u_at = 0, u_span = 0;
    for (const auto& c : r.recs) {
      if (c.fault == static_cast<std::uint8_t>(nodes::Fault::SensorStuck) && t_fault < 0) t_fault = c.t;
      if (c.t >= 3.0 && t_fault < 0) {
        if (u_at == 0) u_at = c.u;
        u_span = std::max(u_span, std::fabs(c.u - u_at));
      }
    }
    EXPECT_GE(t_fault, 3.25);
    EXPECT_LE(t_fault, 5.0);
    std::printf(
        "node (%s), sensor stuck for 2 s: fault %.3f s after it stuck (command moved %.2f V before), "
        "EMCY 0x7300, recovered %llu\n",
        control::toString(kind), t_fault - 3.0, u_span, static_cast<unsigned long long>(r.recoveries));
    const NodeRun twin = runNode(kind, false, nullptr, 8.0);
    EXPECT_EQ(twin.faults, 0u);
  }
}
