// pneumatic_balance: muscle_balance with the pressure's own dynamics - the regulator fills the muscle from
// the supply and vents it to the atmosphere through orifices whose flow depends on the pressures on both
// sides, into a volume that grows as the muscle contracts. The balance's force comes from that pressure P,
// not from the setpoint in (the stage input, the static displacement the setpoint's pressure would give):
//
//   x -> clamp((in - P) / band, -1, 1)  (lag)             the regulator's opening (its proportional band)
//   q  = x rate phi(a / a_sup)                (x > 0)      filling from the supply
//   q  = x rate vent (a / a_sup) phi(a_atm / a)  (x < 0)   venting to the atmosphere
//   P' = (q - n a swell g(y) y') / (1 + swell G(y))       the volume grows with the contraction y: a larger
//                                                          volume fills slower, and contracting expands the
//                                                          air (the pressure falls), extending compresses it
//
// Every pressure is in the balance's units (the static displacement its force would give, as in), where
// P + w is the gauge pressure's force (muscle_balance): a = P + w + span is the absolute pressure (span:
// the atmosphere's), a_sup = supply + span (supply: the supply's gauge pressure), a_atm = span. phi(r)
// is an orifice's flow function of the downstream-to-upstream ratio r: choked (1) up to the critical ratio b, then the
// subsonic ellipse sqrt(1 - ((r - b) / (1 - b))^2) down to 0 at r = 1 (ISO 6358's form; b fitted, it stands as well for
// a nozzle's law, b = 0.528, or a sharp-edged orifice's lower ratio), linear in the pressure difference over the last
// kLaminar of the ratio, where the ellipse's slope grows without bound.
//
// The volume: a muscle's force is its gauge pressure times the volume it gains per unit of contraction
// (F = p dV/dy, the virtual work of an ideal muscle), so the balance's force-length map g is the shape of
// dV/dy as well: V(y) = V(0) (1 + swell G(y)), G(y) = y + a1 y^2 / 2 + a2 y^3 / 3, swell the volume's
// growth at zero contraction over the volume (the tubing's dead volume included). n is the air's
// polytropic index, between isothermal (1) and adiabatic (1.4).
//
// So the muscle vents fast while the flow is choked and ever slower as it nears the atmosphere - an
// exponential approach, not pressure_lag's straight slew - and a payload falling as it vents pushes the
// pressure back up. With a large rate and a narrow band it is muscle_balance. It refines muscle_balance
// and pressure_lag (Effect::refines, warm-started from their parameters) and absorbs saturation as
// muscle_balance does: diagnose tries it in the place of either when the ladder ends above the noise
// with it - with pressure_lag only where the ladder holds saturation too (the stroke's stiffening).
//
// Two refinements a rig needs, both off by default: the regulator's opening follows its error with a
// first-order lag (`lag`, its spool), and a friction element of its own level that the pressure does not
// press (`zc`, `dc`: the payload's guide, a Coulomb friction with a short pre-sliding travel) beside the
// balance's braid friction. The guide's friction may build up with the sliding speed (`vc`, the speed at
// which it reaches half its level, zc |v| / (|v| + vc): a lubricated guide, whose friction at a crawl is
// viscous rather than a break-away); at vc 0 it has its whole level at any speed. The rational law has a
// slope in vc at 0, so a fit can move it from there.
//
// Integration: the balance's sub-steps, each with the pressure advanced first (explicit, not past the
// setpoint by a flow towards it).
#include <algorithm>
#include <cmath>

#include "model/effects/muscle_balance.hpp"

namespace pamc::model {
namespace {

using namespace balance;

constexpr double kLaminar = 0.01;  // the last fraction of the pressure ratio, where the flow is linear in it

// Parameter indices after the balance's; the pressure's state after the balance's states.
enum : int {
  kRate = kNumParams,
  kVent,
  kBand,
  kSpan,
  kSupply,
  kCritical,
  kSwell,
  kPoly,
  kLag,
  kGuide,
  kGuideTravel,
  kGuideSpeed,
  kAllParams
};
enum : int { kP = kNumStates, kOpening, kGuideZ, kAllStates };

// An orifice's flow function of the pressure ratio r (downstream over upstream), 0..1.
double flowFunction(double r, double b) noexcept {
  if (r >= 1.0) return 0.0;
  if (r <= b) return 1.0;
  const double r_lam = 1.0 - kLaminar;
  const double q = (std::min(r, r_lam) - b) / (1.0 - b);
  const double phi = std::sqrt(std::max(1.0 - q * q, 0.0));
  return r <= r_lam ? phi : phi * (1.0 - r) / kLaminar;
}

class PneumaticBalance final : public MuscleBalance {
 public:
  const char* name() const override { return "pneumatic_balance"; }
  const char* explanation() const override {
    return "muscle_balance driven by the muscle's pressure, filled and vented through the valve's orifices whose flow "
           "chokes and falls near the supply and the atmosphere, into a volume that grows as the muscle contracts";
  }
  // It holds muscle_balance (a valve that follows at once) and pressure_lag (the pressure's lag, its rate
  // limited by the flow), and, as muscle_balance, saturation's stiffening.
  std::vector<std::string> refines() const override { return {"muscle_balance", "pressure_lag"}; }
  const std::vector<ParamSpec>& params() const override {
    // The pressure's defaults, in the units of a 40 mm stroke (the bounds scale with the data): a valve
    // that fills the stroke's pressure within tens of milliseconds through a band of a few units, an
    // atmosphere of 25 units and a supply eight times that, ISO 6358's typical critical ratio - chosen,
    // the fit moves them.
    static const std::vector<ParamSpec> p = [] {
      std::vector<ParamSpec> v = MuscleBalance().params();
      v.push_back({"rate", 10.0, 1e5, 2000.0, "y-unit/s"});   // choked filling rate at zero contraction
      v.push_back({"vent", 0.05, 20.0, 1.0, "-"});            // the exhaust's conductance over the supply's
      v.push_back({"band", 0.01, 100.0, 5.0, "y-unit"});      // setpoint error that opens the valve fully
      v.push_back({"span", 0.5, 500.0, 25.0, "y-unit"});      // the atmosphere's absolute pressure
      v.push_back({"supply", 1.0, 2000.0, 200.0, "y-unit"});  // the supply's gauge pressure
      v.push_back({"b", 0.0, 0.9, 0.3, "-"});                 // the orifices' critical pressure ratio
      v.push_back({"swell", 0.0, 0.2, 0.0, "1/y-unit"});      // the volume's growth per unit of contraction
      v.push_back({"n", 1.0, 1.4, 1.2, "-"});                 // the air's polytropic index
      v.push_back({"lag", 0.0, 0.05, 0.0, "s"});              // the regulator's opening: its time constant
      v.push_back({"zc", 0.0, 10.0, 0.0, "y-unit"});          // the guide's friction, not pressed by the pressure
      v.push_back({"dc", 0.001, 2.0, 0.05, "y-unit"});        // ... its pre-sliding travel
      v.push_back({"vc", 0.0, 100.0, 0.0, "y-unit/s"});       // ... the sliding speed of half its level
      return v;
    }();
    return p;
  }
  // The gas's law: the position sees of it only how fast the pressure moves between the supply and the
  // atmosphere, and fits on one record end far apart in it (docs/MODELING.md, "The gas's law from its
  // defaults").
  std::vector<std::string> weaklyHeld() const override { return {"span", "supply", "b", "n"}; }
  // Along the direction muscle_balance's static map leaves open: with a2 small, the balance's rest
  // in + (in + w) a1 y = y keeps its shape for in scaled by s when 1 - a1 w scales by s as well; the
  // pressure's levels follow - the flow's rate and band with the stage input, the supply and the atmosphere
  // with the gauge pressure's force (in + w) at the top of the record - and the friction's growth with
  // the pressure keeps its level at the middle of the record.
  bool scaleAlong(double s, double lo, double hi, double* p) const override {
    const double a1 = p[kA1], w = p[kW], c = 1.0 - a1 * w;
    if (!(std::fabs(a1) > 1e-9) || !(c > 0.0) || !(s > 0.0)) return false;
    const double w2 = (1.0 - s * c) / a1;
    const double top = hi + w, top2 = s * hi + w2, mid = 0.5 * (lo + hi) + w, mid2 = 0.5 * s * (lo + hi) + w2;
    if (!(top > 0.0) || !(top2 > 0.0)) return false;
    p[kW] = w2;
    if (mid > 0.0 && mid2 > 0.0) p[kZp] *= mid / mid2;
    p[kRate] *= s;
    p[kBand] *= s;
    p[kSupply] *= top2 / top;
    p[kSpan] *= top2 / top;
    return true;
  }
  int numStates() const override { return kAllStates; }
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    MuscleBalance::init(p, s, in0, c);
    s[kP] = in0;
    s[kOpening] = 0.0;
    s[kGuideZ] = 0.0;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    Travels d;
    travels(p, d);
    const double h = c.Ts / kSubsteps;
    const double follow = p[kLag] > 0.0 ? 1.0 - std::exp(-h / p[kLag]) : 1.0;
    Local<kAllParams> lp(p);  // as MuscleBalance::step
    Local<kAllStates> ls(s);
    const Guide guide{std::fabs(p[kGuide]), 1.0 / std::max(std::fabs(p[kGuideTravel]), 1e-9), ls.v + kGuideZ,
                      std::fabs(p[kGuideSpeed])};
    for (int i = 0; i < kSubsteps; ++i) {
      ls.v[kP] = pressureStep(lp.v, ls.v, in, h, follow);
      subStep(lp.v, d, ls.v, ls.v[kP], guide);
    }
    ls.store(s);
    return s[kY];
  }

 private:
  // The pressure after one sub-step h towards the setpoint in, with the volume's change by the motion.
  static double pressureStep(const double* p, double* s, double in, double h, double follow) noexcept {
    const double span = std::max(std::fabs(p[kSpan]), 1e-6);
    const double vac = -p[kW] - span;  // the level of zero absolute pressure (gauge zero at in = -w)
    const double a_sup = std::max(p[kSupply], 0.0) + span;
    const double P = s[kP];
    const double a = std::max(P - vac, 1e-9);
    const double e = in - P;
    s[kOpening] += follow * (std::clamp(e / std::max(std::fabs(p[kBand]), 1e-6), -1.0, 1.0) - s[kOpening]);
    const double x = s[kOpening];
    const double phi = x > 0.0 ? flowFunction(a / a_sup, p[kCritical])
                               : (a / a_sup) * flowFunction(span / a, p[kCritical]) * std::fabs(p[kVent]);
    const double y = s[kY], swell = std::fabs(p[kSwell]);
    const double cap = std::max(1.0 + swell * y * (1.0 + y * (p[kA1] / 2.0 + y * p[kA2] / 3.0)), 0.1);
    double flow = x * std::fabs(p[kRate]) * phi * h / cap;
    if (flow * e > 0.0) flow = e > 0.0 ? std::min(flow, e) : std::max(flow, e);  // not past the setpoint
    const double g = 1.0 + y * (p[kA1] + y * p[kA2]);
    const double motion = p[kPoly] * a * swell * g * s[kV] * h / cap;
    return std::max(P + flow - motion, vac);
  }
};

static_assert(kAllStates <= kMaxEffectStates, "pneumatic_balance's states fit an effect's storage");

}  // namespace
std::unique_ptr<Effect> make_pneumatic_balance() { return std::make_unique<PneumaticBalance>(); }
}  // namespace pamc::model
