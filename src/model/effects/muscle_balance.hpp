// The muscle's force balance (muscle_balance.cpp describes it), shared with its form with the pressure's
// own dynamics (pneumatic_balance.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "model/bouc_wen.hpp"
#include "model/effect.hpp"
#include "model/effects/second_order.hpp"

namespace pamc::model::balance {

constexpr int kSubsteps = 4;
constexpr int kElements = 3;

// Parameter indices.
enum : int { kFn, kZeta, kZmax, kDelta, kW, kA1, kA2, kZp, kSpread, kLo, kHi, kNumParams };
// State indices: position, velocity, the Dahl elements, then the cached sub-step map (A row-major, B).
enum : int { kY = 0, kV = 1, kZ0 = 2, kMap = kZ0 + kElements, kNumStates = kMap + 6 };

class MuscleBalance : public Effect {
 public:
  const char* name() const override { return "muscle_balance"; }
  const char* explanation() const override {
    return "the muscle's force-length-pressure map in the payload's force balance, with braid friction of several "
           "break-away levels growing with the pressure, and the end stops";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 40; }  // force_loop's place: the last block of the chain
  const char* alternativeTo() const override { return "mass_spring"; }
  std::vector<std::string> refines() const override { return {"mass_spring", "force_loop", "friction_hysteresis"}; }
  std::vector<std::string> absorbs() const override { return {"saturation"}; }
  double coreReach() const override { return 2.0; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"fn", 0.2, 100.0, 10.0, "Hz"},  // payload against the nominal stiffness
        {"zeta", 0.01, 1.0, 0.5, "-"},
        {"zmax", 0.0, 10.0, 0.5, "y-unit"},        // friction's level at no pressure, over the stiffness
        {"delta", 0.01, 20.0, 0.5, "y-unit"},      // shortest pre-sliding travel
        {"w", -100.0, 100.0, 0.0, "y-unit"},       // weight and preload over the stiffness
        {"a1", -0.1, 0.1, 0.0, "1/y-unit"},        // force-length map: slope ...
        {"a2", -0.005, 0.005, 0.0, "1/y-unit^2"},  // ... and curvature
        {"zp", 0.0, 0.2, 0.0, "-"},                // friction's growth with the pressure's force
        {"spread", 1.0, 20.0, 1.0, "-"},           // longest over shortest pre-sliding travel
        {"lo", -1e9, 1e9, -1e9, "y-stop"},         // end stops (outside the data: none)
        {"hi", -1e9, 1e9, 1e9, "y-stop"},
    };
    return p;
  }
  // The map a muscle can have that rests the stage inputs xs nearest ys: convex (a2 >= 0, as Tondu-Lopez's
  // and the exponential laws are, whichever way the output counts) and the pressure's force positive over
  // the record (x + w > 0), by least squares on (x + w) (a1 y + a2 y^2) = y - x over a logarithmic grid of
  // weights. False where no such map stays stiff at every point.
  bool seedRest(const std::vector<double>& xs, const std::vector<double>& ys, double* p) const override {
    const auto [lo, hi] = std::minmax_element(xs.begin(), xs.end());
    const double span = std::max(*hi - *lo, 1e-9);
    constexpr int kWeights = 25;
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < kWeights; ++k) {
      const double w = -*lo + span * 0.05 * std::pow(200.0, static_cast<double>(k) / (kWeights - 1));
      const Map m = convexMap(xs, ys, w);
      if (m.cost < best) best = m.cost, p[kW] = w, p[kA1] = m.a1, p[kA2] = m.a2;
    }
    return std::isfinite(best);
  }
  int numStates() const override { return kNumStates; }
  int numFilterStates() const override { return 2; }  // y, v: the core reaches y through them
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    secondOrderMap(p[kFn], p[kZeta], c.Ts / kSubsteps, s + kMap);
    s[kY] = std::clamp(restPosition(p, in0), std::min(p[kLo], p[kHi]), std::max(p[kLo], p[kHi]));
    s[kV] = 0.0;
    for (int i = 0; i < kElements; ++i) s[kZ0 + i] = 0.0;
  }
  double step(const double* p, double* s, double in, const StepContext&) const noexcept override {
    Travels d;  // their inverses
    travels(p, d);
    // The sub-steps on local copies: through the pointers, the compiler could not keep the parameters in
    // registers across a state's store (a fit simulates a record sample by sample).
    Local<kNumParams> lp(p);
    Local<kNumStates> ls(s);
    for (int i = 0; i < kSubsteps; ++i) subStep(lp.v, d, ls.v, in);
    ls.store(s);
    return s[kY];
  }

 protected:
  // A copy of n values of an effect's parameters or states.
  template <int n>
  struct Local {
    double v[n];
    explicit Local(const double* from) noexcept { std::copy(from, from + n, v); }
    void store(double* to) const noexcept { std::copy(v, v + n, to); }
  };

  // seedRest's least squares at the weight w, with a2 >= 0 (the map convex): the unconstrained solution,
  // else the one with a2 = 0; cost infinite where the balance would lose its stiffness at a point.
  struct Map {
    double a1 = 0.0, a2 = 0.0, cost = std::numeric_limits<double>::infinity();
  };
  static Map convexMap(const std::vector<double>& xs, const std::vector<double>& ys, double w) noexcept {
    double s11 = 0, s12 = 0, s22 = 0, r1 = 0, r2 = 0, rr = 0;
    for (size_t i = 0; i < xs.size() && i < ys.size(); ++i) {
      const double f1 = (xs[i] + w) * ys[i], f2 = f1 * ys[i], r = ys[i] - xs[i];
      s11 += f1 * f1, s12 += f1 * f2, s22 += f2 * f2, r1 += f1 * r, r2 += f2 * r, rr += r * r;
    }
    const auto cost = [&](double a1, double a2) {
      for (size_t i = 0; i < xs.size() && i < ys.size(); ++i)
        if (!((xs[i] + w) * (a1 + 2.0 * a2 * ys[i]) < 1.0)) return std::numeric_limits<double>::infinity();
      return rr - 2.0 * (a1 * r1 + a2 * r2) + a1 * a1 * s11 + 2.0 * a1 * a2 * s12 + a2 * a2 * s22;
    };
    const double det = s11 * s22 - s12 * s12;
    if (det > 1e-12 * s11 * s22) {
      const double a1 = (r1 * s22 - r2 * s12) / det, a2 = (s11 * r2 - s12 * r1) / det;
      if (a2 >= 0.0) return {a1, a2, cost(a1, a2)};
    }
    const double a1 = s11 > 0.0 ? r1 / s11 : 0.0;
    return {a1, 0.0, cost(a1, 0.0)};
  }

  // The map's force over the nominal stiffness beyond the linear spring: (in + w) g(y) - w - in.
  static double mapExcess(const double* p, double in, double y) noexcept {
    return (in + p[kW]) * (p[kA1] * y + p[kA2] * y * y);
  }
  static double level(const double* p, double in) noexcept {
    return std::fabs(p[kZmax]) + std::fabs(p[kZp]) * std::max(in + p[kW], 0.0);
  }
  // The inverses of the elements' pre-sliding travels: delta, delta sqrt(spread), delta spread.
  using Travels = double[kElements];
  static void travels(const double* p, Travels& d) noexcept {
    const double spread = std::sqrt(std::max(p[kSpread], 1.0));
    d[0] = 1.0 / std::max(std::fabs(p[kDelta]), 1e-9);
    for (int i = 1; i < kElements; ++i) d[i] = d[i - 1] / spread;
  }

  // Static equilibrium without friction, in + mapExcess(y) = y, by a few Newton steps from y = in.
  static double restPosition(const double* p, double in) noexcept {
    double y = in;
    for (int k = 0; k < 30; ++k) {
      const double f = in + mapExcess(p, in, y) - y;
      const double df = (in + p[kW]) * (p[kA1] + 2.0 * p[kA2] * y) - 1.0;
      if (!(df < -1e-6)) break;  // the balance lost its stiffness: keep the last point
      const double dy = -f / df;
      y += dy;
      if (std::fabs(dy) < 1e-12) break;
    }
    return std::isfinite(y) ? y : in;
  }

  // A friction element of its own level, not pressed by the pressure (pneumatic_balance's guide): its
  // level, the inverse of its pre-sliding travel, its state, and the sliding speed at which it reaches half
  // its level (0: its whole level at any speed, Dahl's rate-independent element). None at level 0.
  struct Guide {
    double level = 0.0, inv_travel = 0.0;
    double* z = nullptr;
    double half_speed = 0.0;
    // Its level at the speed v: a lubricated guide's friction builds up with the sliding speed.
    double levelAt(double v) const noexcept {
      const double s = std::fabs(v);
      return half_speed > 0.0 ? level * s / (s + half_speed) : level;
    }
  };

  // One sub-step of the balance under the static displacement `in` of the pressure's force.
  static void subStep(const double* p, const Travels& d, double* s, double in) noexcept {
    subStep(p, d, s, in, Guide{});
  }
  static void subStep(const double* p, const Travels& d, double* s, double in, const Guide& guide) noexcept {
    const double y = s[kY], v = s[kV];
    const double lvl = level(p, in);
    double z = 0.0, slope_pos = 0.0, slope_neg = 0.0;  // friction, and its slope dz/dy moving up / down
    for (int i = 0; i < kElements; ++i) {
      const double zi = s[kZ0 + i];
      z += zi;
      slope_pos += (1.0 - zi) * d[i];
      slope_neg += (1.0 + zi) * d[i];
    }
    const double scale = lvl / kElements;
    z *= scale;
    slope_pos *= scale;
    slope_neg *= scale;
    const bool guided = guide.level > 0.0 && guide.z != nullptr;
    if (guided) {
      const double g = guide.levelAt(v);  // at the sub-step's start; its change with the speed: below
      z += g * *guide.z;
      slope_pos += g * (1.0 - *guide.z) * guide.inv_travel;
      slope_neg += g * (1.0 + *guide.z) * guide.inv_travel;
    }
    // The payload under the force of the sub-step's start.
    const double force = in + mapExcess(p, in, y) - z;
    double y1 = s[kMap + 0] * y + s[kMap + 1] * v + s[kMap + 4] * force;
    double v1 = s[kMap + 2] * y + s[kMap + 3] * v + s[kMap + 5] * force;
    if ((lvl > 0.0 || guided) && y1 != y) {
      // The friction stiffens by its slope over the sub-step, taken at its end (implicit, as force_loop).
      const double g = y1 > y ? slope_pos : slope_neg;
      const double b0 = std::max(s[kMap + 4], 0.0), b1 = s[kMap + 5];
      const double shrink = 1.0 / (1.0 + b0 * g);
      const double dz = g * (y1 - y) * shrink;
      y1 = y + (y1 - y) * shrink;
      v1 -= b1 * dz;
    }
    if (guided) guideDamping(guide, v, s[kMap + 4], s[kMap + 5], y1, v1);
    advanceFriction(d, s, y1 - y);
    if (guided) advanceElement(*guide.z, y1 - y, guide.inv_travel);
    endStops(p, y1, v1);
    s[kY] = y1;
    s[kV] = v1;
  }

  // The guide's friction grows with the speed by the slope D = level |z| vc / (|v| + vc)^2 where it opposes
  // the motion: a damper, taken implicitly (linearised at the sub-step's start speed v), for near rest D
  // reaches level / vc - at a small vc far beyond what an explicit sub-step can carry. Against the motion
  // (pre-sliding after a reversal) it is left explicit: there it is bounded by the level.
  static void guideDamping(const Guide& guide, double v, double b0, double b1, double& y1, double& v1) noexcept {
    if (!(guide.half_speed > 0.0) || *guide.z * v < 0.0) return;
    const double s = std::fabs(v) + guide.half_speed;
    const double damp = guide.level * std::fabs(*guide.z) * guide.half_speed / (s * s);
    const double k = std::max(b1, 0.0) * damp;
    const double v_new = (v1 + k * v) / (1.0 + k);
    y1 -= std::max(b0, 0.0) * damp * (v_new - v);
    v1 = v_new;
  }

  // Each Dahl element exactly along the travel dy: z -> sgn + (z - sgn) exp(-|dy| / delta_i).
  static void advanceFriction(const Travels& d, double* s, double dy) noexcept {
    for (int i = 0; i < kElements; ++i) advanceElement(s[kZ0 + i], dy, d[i]);
  }
  static void advanceElement(double& z, double dy, double inv_travel) noexcept {
    if (dy == 0.0) return;
    const double sgn = dy > 0.0 ? 1.0 : -1.0;
    if (z == sgn) return;  // sliding: stays at its level
    // exp(-x) = 1 - x (1 - exp(-x)) / x: the Bouc-Wen core's series below its limit (no exp on a
    // sub-step's short travel, within 2e-12 relative), exp above it.
    const double x = std::fabs(dy) * inv_travel;
    const double decay = x < detail::kSeriesLimit ? 1.0 - x * detail::boucWenSeries(x) : std::exp(-x);
    z = sgn + (z - sgn) * decay;
  }

  // A payload past a stop rests on it; its velocity into the stop is lost.
  static void endStops(const double* p, double& y, double& v) noexcept {
    const double lo = std::min(p[kLo], p[kHi]), hi = std::max(p[kLo], p[kHi]);
    if (y < lo) {
      y = lo;
      v = std::max(v, 0.0);
    } else if (y > hi) {
      y = hi;
      v = std::min(v, 0.0);
    }
  }
};

static_assert(kNumStates <= kMaxEffectStates, "muscle_balance's states fit an effect's storage");

}  // namespace pamc::model::balance
