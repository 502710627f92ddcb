// The test oracle's simulator: see oracle_sim.hpp. Nothing here comes from src/.
#include "oracle_sim.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

namespace pamc::oracle {

// ---------------------------------------------------------------------------------------------
// Effects: names, parameters and bounds as pamc's catalogue (for a 40 mm / 10 V / 1 kHz rig).

namespace {
// The payload's force balance: muscle_balance's parameters, and pneumatic_balance's first ones.
std::vector<ParamInfo> balanceParams() {
  return {{"fn", 0.2, 100.0, 10.0}, {"zeta", 0.01, 3.0, 0.5}, {"w", -100.0, 100.0, 0.0},    {"L", 5.0, 1e4, 1e4},
          {"f0", 0.0, 10.0, 0.0},   {"fp", 0.0, 0.2, 0.0},    {"k_slip", 0.01, 100.0, 1.0}, {"spread", 1.0, 100.0, 1.0},
          {"lo", -1e9, 1e9, -1e9},  {"hi", -1e9, 1e9, 1e9},   {"fg", 0.0, 10.0, 0.0},       {"vg", 0.01, 100.0, 1.0}};
}
std::vector<ParamInfo> withBalance(const std::vector<ParamInfo>& more) {
  auto p = balanceParams();
  p.insert(p.end(), more.begin(), more.end());
  return p;
}
}  // namespace

const std::vector<EffectInfo>& effectTable() {
  static const std::vector<EffectInfo> t = {
      {"pressure_lag",
       {{"tau", 1e-3, 2.0, 0.05}, {"slew", 1.0, 1000.0, 1000.0}},
       false,
       "effective command follows the valve command with a first-order lag and a rate limit"},
      {"asymmetry",
       {{"gain", -10.0, 10.0, 1.0}, {"w_up", 0.05, 10.0, 1.0}, {"w_down", 0.05, 10.0, 0.3}},
       false,
       "extra hysteretic element of the command turning round over w_up rising, w_down falling"},
      {"creep",
       {{"fraction", -0.5, 0.5, 0.05}, {"tau", 0.2, 200.0, 5.0}},
       false,
       "viscoelastic drift towards a further fraction of the displacement with time constant tau"},
      {"mass_spring",
       {{"fn", 0.2, 100.0, 10.0}, {"zeta", 0.01, 3.0, 0.5}},
       false,
       "payload inertia: second-order response of the displacement"},
      {"force_loop",
       {{"fn", 0.2, 100.0, 10.0}, {"zeta", 0.01, 1.0, 0.5}, {"zmax", 0.0, 10.0, 0.5}, {"delta", 0.01, 2.0, 0.5}},
       false,
       "payload inertia with Dahl friction inside its force balance"},
      {"friction_hysteresis",
       {{"zmax", 0.0, 10.0, 0.5}, {"delta", 0.01, 20.0, 0.5}},
       false,
       "Dahl friction driven by the output's own motion: sticks after every reversal"},
      {"delay", {{"d", 0.0, 0.25, 0.01}}, false, "pure transport delay of the command"},
      {"dead_band", {{"threshold", -5.0, 5.0, -5.0}}, false, "command cut off below the threshold"},
      {"load", {{"compliance", -10.0, 10.0, 0.05}}, true, "displacement drops by compliance x load"},
      {"saturation",
       {{"knee", 0.0, 40.0, 30.0}, {"width", 0.1, 80.0, 10.0}},
       false,
       "displacement flattens above the knee towards knee + width"},
      {"muscle_balance", balanceParams(), false,
       "payload's force balance with an exponential force-length map, elastoplastic Maxwell-slip friction whose "
       "levels grow with the pressure, and inelastic end stops"},
      {"pneumatic_balance",
       withBalance({{"rate", 10.0, 1e5, 1000.0},
                    {"vent", 0.05, 20.0, 1.0},
                    {"band", 0.01, 100.0, 1.0},
                    {"span", 0.5, 500.0, 14.0},
                    {"supply", 1.0, 2000.0, 100.0},
                    {"swell", 0.0, 0.2, 0.0},
                    {"n", 1.0, 1.4, 1.3}}),
       false,
       "muscle_balance driven by the muscle's own pressure: a regulator fills it from the supply and vents it to "
       "the atmosphere through isentropic nozzles, polytropic air in a volume that grows with the contraction"},
      {"warm_up",
       {{"tau", 1.0, 3600.0, 60.0}, {"gain", -0.5, 0.5, 0.1}, {"shift", -10.0, 10.0, 0.0}},
       false,
       "travel grows and length shifts with a thermal time constant after the start"},
      // Outside pamc's catalogue (unseen.json): physics the model has no effect for.
      {"dead_zone",
       {{"centre", -5.0, 5.0, 0.0}, {"width", 0.01, 3.0, 0.3}},
       false,
       "outside the catalogue: no response within +-width of the centre, the command shifted by the width "
       "outside (an overlapped spool)"},
      {"piecewise_gain",
       {{"knee", -5.0, 5.0, 1.0}, {"gain", 0.05, 5.0, 0.5}},
       false,
       "outside the catalogue: the command's gain changes to `gain` above the knee"},
      {"input_saturation",
       {{"lo", -5.0, 5.0, -5.0}, {"hi", -5.0, 5.0, 5.0}},
       false,
       "outside the catalogue: the command clipped to [lo, hi] (the regulator's range ends early)"},
      {"direction_lag",
       {{"tau_up", 1e-3, 2.0, 0.05}, {"tau_down", 1e-3, 2.0, 0.2}},
       false,
       "outside the catalogue: a first-order lag, faster rising (filling) than falling (venting)"},
      {"valve_flow",
       {{"rate", 0.1, 100.0, 5.0}, {"eps", 1e-4, 1.0, 0.01}},
       false,
       "outside the catalogue: orifice flow, the effective command moves at rate sqrt(|difference|)"},
      {"backlash",
       {{"width", 0.0, 10.0, 0.5}},
       false,
       "outside the catalogue: play of `width` mm between the muscle and the sensor"},
      {"periodic_disturbance",
       {{"amplitude", 0.0, 5.0, 0.05}, {"freq", 0.1, 200.0, 7.3}, {"phase", -360.0, 360.0, 0.0}},
       false,
       "outside the catalogue: a sinusoidal vibration added to the position, unrelated to the command"},
      {"play_hysteresis",
       {{"r1", 0.01, 5.0, 0.3},
        {"w1", -10.0, 10.0, 0.5},
        {"r2", 0.01, 5.0, 0.8},
        {"w2", -10.0, 10.0, 0.4},
        {"r3", 0.01, 5.0, 1.5},
        {"w3", -10.0, 10.0, 0.3}},
       false,
       "outside the catalogue: a Prandtl-Ishlinskii sum of three play operators of the command added to y"},
  };
  return t;
}

const EffectInfo& effectInfo(const std::string& name) {
  for (const auto& e : effectTable())
    if (e.name == name) return e;
  std::string known;
  for (const auto& e : effectTable()) known += (known.empty() ? "" : ", ") + e.name;
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + known + ")");
}

namespace {

std::string trim(const std::string& s) {
  size_t a = s.find_first_not_of(" \t"), b = s.find_last_not_of(" \t");
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char ch : s) {
    if (ch == sep) {
      out.push_back(trim(cur));
      cur.clear();
    } else {
      cur += ch;
    }
  }
  out.push_back(trim(cur));
  return out;
}

double parseNumber(const std::string& s, const std::string& what) {
  const std::string t = trim(s);
  if (t.empty()) throw std::invalid_argument(what + ": missing number");
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(t.c_str(), &end);
  if (end != t.c_str() + t.size() || errno == ERANGE || !std::isfinite(v))
    throw std::invalid_argument(what + ": '" + t + "' is not a finite number");
  return v;
}

// "key=value,key=value" into a map (empty string: empty map).
std::map<std::string, double> parseKeyValues(const std::string& s, const std::string& what) {
  std::map<std::string, double> out;
  if (trim(s).empty()) return out;
  for (const auto& item : split(s, ',')) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0)
      throw std::invalid_argument(what + ": expected key=value, got '" + item + "'");
    const std::string key = trim(item.substr(0, eq));
    if (out.count(key)) throw std::invalid_argument(what + ": '" + key + "' given twice");
    out[key] = parseNumber(item.substr(eq + 1), what + " " + key);
  }
  return out;
}

}  // namespace

EffectSpec parseEffect(const std::string& text) {
  EffectSpec e;
  const auto colon = text.find(':');
  e.name = trim(text.substr(0, colon));
  const EffectInfo& info = effectInfo(e.name);
  if (colon != std::string::npos) e.params = parseKeyValues(text.substr(colon + 1), "effect " + e.name);
  for (const auto& [k, v] : e.params) {
    (void)v;
    bool ok = false;
    for (const auto& p : info.params) ok = ok || p.name == k;
    if (!ok) {
      std::string known;
      for (const auto& p : info.params) known += (known.empty() ? "" : ", ") + p.name;
      throw std::invalid_argument("effect " + e.name + " has no parameter '" + k + "' (its parameters: " + known + ")");
    }
  }
  return e;
}

Core parseCore(const std::string& text, Core c) {
  for (const auto& [k, v] : parseKeyValues(text, "core")) {
    if (k == "k")
      c.k = v;
    else if (k == "rho")
      c.rho = v;
    else if (k == "b")
      c.b = v;
    else if (k == "alpha")
      c.alpha = v;
    else if (k == "beta")
      c.beta = v;
    else if (k == "gamma")
      c.gamma = v;
    else
      throw std::invalid_argument("core has no parameter '" + k + "' (k, rho, b, alpha, beta, gamma)");
  }
  return c;
}

void validateEffects(const std::vector<EffectSpec>& effects) {
  std::set<std::string> seen;
  for (const auto& e : effects) {
    const EffectInfo& info = effectInfo(e.name);
    if (!seen.insert(e.name).second) throw std::invalid_argument("effect " + e.name + " given twice");
    for (const auto& [k, v] : e.params) {
      const ParamInfo* pi = nullptr;
      for (const auto& p : info.params)
        if (p.name == k) pi = &p;
      if (!pi) throw std::invalid_argument("effect " + e.name + " has no parameter '" + k + "'");
      if (!(v >= pi->lo && v <= pi->hi)) {
        std::ostringstream os;
        os << "effect " << e.name << ": " << k << " = " << v << " outside [" << pi->lo << ", " << pi->hi << "]";
        throw std::invalid_argument(os.str());
      }
    }
  }
  if (seen.count("mass_spring") + seen.count("force_loop") + seen.count("muscle_balance") +
          seen.count("pneumatic_balance") >
      1)
    throw std::invalid_argument(
        "mass_spring, force_loop, muscle_balance and pneumatic_balance are alternatives: take one");
  for (const char* name : {"muscle_balance", "pneumatic_balance"}) {
    if (!seen.count(name)) continue;
    const EffectSpec& e =
        *std::find_if(effects.begin(), effects.end(), [&](const EffectSpec& x) { return x.name == name; });
    auto at = [&](const char* k, double def) { return e.params.count(k) ? e.params.at(k) : def; };
    if (!(at("lo", -1e9) < at("hi", 1e9)))
      throw std::invalid_argument("effect " + std::string(name) + ": lo must be below hi");
  }
  if (seen.count("pressure_lag") + seen.count("direction_lag") + seen.count("valve_flow") > 1)
    throw std::invalid_argument("pressure_lag, direction_lag and valve_flow are alternatives: take one");
}

// ---------------------------------------------------------------------------------------------
// pneumatic_balance's air (oracle_sim.hpp): isentropic nozzles, polytropic air, the volume of the map.

namespace {
constexpr double kKappa = 1.4;
// The critical ratio (2 / (k + 1))^(k / (k - 1)) = 0.5283
const double kCritical = std::pow(2.0 / (kKappa + 1.0), kKappa / (kKappa - 1.0));
}  // namespace

double PneumaticAir::psi(double r) {
  r = std::clamp(r, kCritical, 1.0);  // choked below the critical ratio
  const double v = std::pow(r, 2.0 / kKappa) - std::pow(r, (kKappa + 1.0) / kKappa);
  return std::sqrt(2.0 * kKappa / (kKappa - 1.0) * std::max(v, 0.0));
}

double PneumaticAir::opening(double y, double p) const { return std::clamp((y - p) / band, -1.0, 1.0); }

double PneumaticAir::volume(double x) const { return 1.0 + swell * L * -std::expm1(-x / L); }

double PneumaticAir::flow(double p, double o) const {
  // Mass flow through a nozzle from P_u to P_d (P_u psi(P_d / P_u)), reversed when P_d > P_u.
  auto nozzle = [](double pu, double pd) { return pu >= pd ? pu * psi(pd / pu) : -pd * psi(pu / pd); };
  const double P = p + w + span, Ps = supply + span, Pa = span;
  const double scale = rate / (Ps * psi(0.0));  // choked filling at o = 1: q = rate
  if (o > 0.0) return scale * o * nozzle(Ps, P);
  if (o < 0.0) return scale * vent * -o * -nozzle(P, Pa);
  return 0.0;
}

double PneumaticAir::pressureRate(double y, double p, double x, double xd) const {
  const double P = p + w + span;
  const double vd = swell * std::exp(-x / L) * xd;
  return n / volume(x) * (flow(p, opening(y, p)) - P * vd);
}

PneumaticAir pneumaticAir(const EffectSpec& e) {
  if (e.name != "pneumatic_balance") throw std::invalid_argument("not pneumatic_balance: " + e.name);
  auto at = [&](const char* k) {
    auto it = e.params.find(k);
    if (it != e.params.end()) return it->second;
    for (const auto& p : effectInfo(e.name).params)
      if (p.name == k) return p.def;
    throw std::invalid_argument(std::string("no parameter ") + k);
  };
  PneumaticAir a;
  a.rate = at("rate"), a.vent = at("vent"), a.band = at("band"), a.span = at("span"), a.supply = at("supply");
  a.swell = at("swell"), a.n = at("n"), a.w = at("w"), a.L = at("L");
  return a;
}

double Record::noise() const { return std::sqrt(noise_std * noise_std + quantum * quantum / 12.0); }

// ---------------------------------------------------------------------------------------------
// The continuous-time system.

namespace {

constexpr int kSlipElements = 4;  // muscle_balance's Maxwell-slip elements
enum : int { kV, kL, kP, kH, kZa, kZc, kZf, kX, kXd, kZl, kPr, kE0, kN = kE0 + kSlipElements };
using Vec = std::array<double, kN>;

double param(const EffectSpec& e, const std::string& name) {
  auto it = e.params.find(name);
  if (it != e.params.end()) return it->second;
  for (const auto& p : effectInfo(e.name).params)
    if (p.name == name) return p.def;
  throw std::logic_error("no parameter " + name);
}

double sgn(double x) { return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : 0.0; }

// muscle_balance in the oracle's own laws (forces over the nominal stiffness, in mm; s the stage input):
//   x'' = wn^2 (F(s, x) - x - F_f) - 2 zeta wn x'
//   F(s, x) = (s + w) exp(-x / L) - w            exponential force-length map (s + w: the pressure's force)
//   F_f = sum_i k_i (x - q_i)                    elastoplastic Maxwell-slip elements, i = 0..3: a spring k_i
//   q_i = clamp(q_i, x - E_i, x + E_i)           from x to its anchor q_i, which slips when the spring's force
//                                                reaches the break-away k_i E_i (a play operator of x)
//   k_i = k_slip spread^(-i / 3),  E_i = N(s) / (4 k_i),  N(s) = f0 + fp max(s + w, 0)
//   F_g = fg (1 - exp(-|x'| / vg)) sgn(x')        the payload's guide: a friction of its own level fg, not
//                                                pressed by the pressure, building up with the sliding speed
//                                                over vg (none at fg 0)
//   at a stop (x = lo or hi) with the net force into it the payload rests: x' = x'' = 0
// The anchors are algebraic: within a step they are clamped from the step's start, and the step is cut
// where the payload turns round or meets a stop, so x is monotone over every step and the clamp exact.
struct Balance {
  double w = 0, L = 1e4, f0 = 0, fp = 0, k_slip = 1, spread = 1, lo = -1e9, hi = 1e9, fg = 0, vg = 1;
  static constexpr double kStopTol = 1e-9;  // [mm] how close to a stop a contact is made
  static constexpr double kTurnTol = 1e-6;  // [mm/s] how small the velocity past a turn may be

  double muscle(double s, double x) const { return (s + w) * std::exp(-x / L) - w; }
  double level(double s) const { return f0 + fp * std::max(s + w, 0.0); }
  double levelRate(double s, double sd) const { return s + w > 0.0 ? fp * sd : 0.0; }
  double stiffness(int i) const { return k_slip * std::pow(spread, -static_cast<double>(i) / (kSlipElements - 1)); }

  // The position at rest with the elements unloaded, F(s, x) = x (Newton from x = s: for s + w >= 0 the
  // difference is convex and falling), held within the stops.
  double rest(double s) const {
    double x = s;
    for (int it = 0; it < 100; ++it) {
      const double e = std::exp(-x / L), g = (s + w) * e - w - x, dg = -(s + w) * e / L - 1.0;
      const double dx = g / dg;
      x -= dx;
      if (std::fabs(dx) < 1e-14 * (1.0 + std::fabs(x))) break;
    }
    return std::clamp(x, lo, hi);
  }

  // The friction force F_f; the anchors slipped to the position x[kX] and the level at s.
  double friction(Vec& x, double s) const {
    double f = 0.0;
    const double n = level(s) / kSlipElements;
    for (int i = 0; i < kSlipElements; ++i) {
      const double k = stiffness(i), E = n / k;
      double& q = x[kE0 + i];
      q = std::clamp(q, x[kX] - E, x[kX] + E);
      f += k * (x[kX] - q);
    }
    return f;
  }

  // The guide's friction at the velocity v.
  double guide(double v) const { return fg > 0.0 ? fg * (1.0 - std::exp(-std::fabs(v) / vg)) * sgn(v) : 0.0; }

  // The payload's rates for stage input s into d (the anchors' are 0); returns the position.
  double rates(Vec& x, double s, double wn, double zeta, Vec& d) const {
    const double a = wn * wn * (muscle(s, x[kX]) - x[kX] - friction(x, s) - guide(x[kXd])) - 2.0 * zeta * wn * x[kXd];
    const bool held = (x[kX] <= lo && x[kXd] <= 0.0 && a <= 0.0) || (x[kX] >= hi && x[kXd] >= 0.0 && a >= 0.0);
    d[kX] = held ? 0.0 : x[kXd];
    d[kXd] = held ? 0.0 : a;
    return x[kX];
  }

  // The fraction of the step from x to xn at which the payload meets a stop (xn beyond it by more than
  // kStopTol) or turns round (the velocity changes sign and ends above kTurnTol); 1 when neither.
  double eventFraction(const Vec& x, const Vec& xn) const {
    const double a = x[kX], b = xn[kX], va = x[kXd], vb = xn[kXd];
    if (b < lo - kStopTol && a >= lo - kStopTol) return std::clamp((a - lo) / (a - b), 0.0, 1.0);
    if (b > hi + kStopTol && a <= hi + kStopTol) return std::clamp((hi - a) / (b - a), 0.0, 1.0);
    if (va * vb < 0.0 && std::fabs(vb) > kTurnTol) return std::clamp(va / (va - vb), 0.0, 1.0);
    return 1.0;
  }
  // A payload within kStopTol of a stop and moving into it comes to rest on it (inelastic contact).
  bool settle(Vec& xn) const {
    const bool at_lo = xn[kX] <= lo + kStopTol && xn[kXd] < 0.0;
    const bool at_hi = xn[kX] >= hi - kStopTol && xn[kXd] > 0.0;
    if (!at_lo && !at_hi) return false;
    xn[kX] = at_lo ? lo : hi;
    xn[kXd] = 0.0;
    return true;
  }
};

// The valve stage's output v and the load signal L with their rates at some time.
struct Drive {
  double v, vd, L, Ld;
};

struct System {
  Core c;
  double tv = 1e-6;
  bool dead = false, lag = false, asym = false, load = false, sat = false, creep = false, fric = false, mass = false,
       floop = false, mb = false, pb = false, warm = false;
  Balance bal;
  PneumaticAir air;  // pneumatic_balance's (pb): the balance driven by the pressure state x[kPr]
  double delay = 0.0;
  double thr = 0, lag_tau = 0, lag_slew = 0;
  double as_gain = 0, as_wu = 1, as_wd = 1;
  double compliance = 0;
  double knee = 0, width = 1;
  double cr_frac = 0, cr_tau = 1;
  double fr_zmax = 0, fr_delta = 1;
  double wn = 1, zeta = 0, fl_zmax = 0, fl_delta = 1;
  double wu_tau = 1, wu_gain = 0, wu_shift = 0;
  double y_start = 0.0;  // warm_up's displacement at t = 0
  // Outside the catalogue (input stage; the output stage's are applied per sample, OutputStage).
  bool dz = false, pwg = false, isat = false, dlag = false, vflow = false;
  double dz_c = 0, dz_w = 0, pw_knee = 0, pw_gain = 1, is_lo = -5, is_hi = 5, tau_up = 1, tau_down = 1;
  double vf_rate = 1, vf_eps = 0.01;

  // The input stage outside the catalogue, before the lags: s and its rate sd.
  void unseenInput(double& s, double& sd) const {
    if (dz) {
      const double e = s - dz_c;
      if (std::fabs(e) <= dz_w)
        s = dz_c, sd = 0.0;
      else
        s = s - sgn(e) * dz_w;
    }
    if (pwg && s > pw_knee) s = pw_knee + pw_gain * (s - pw_knee), sd *= pw_gain;
    if (isat && (s < is_lo || s > is_hi)) s = std::clamp(s, is_lo, is_hi), sd = 0.0;
  }
  // The lags outside the catalogue: the rate of the lagged command p towards s.
  double unseenLagRate(double s, double p) const {
    if (dlag) return (s - p) / (s > p ? tau_up : tau_down);
    const double e = s - p;
    return vf_rate * e / std::sqrt(std::fabs(e) + vf_eps);
  }

  // The output of the chain for states x at time t, valve stage output and load (and their rates)
  // given by dr; the state derivatives into dx when non-null. With `rest`, the states are first put at
  // rest for dr (every filter at its input, h and the friction states 0).
  double eval(double t, Vec& x, const Drive& dr, Vec* dx, bool rest) const {
    if (rest) {
      x.fill(0.0);
      x[kV] = dr.v;
      x[kL] = dr.L;
    }
    Vec d{};  // d[kV] = d[kL] = 0: the integrator moves v and L by their closed form
    // Input stage.
    double s = dr.v, sd = dr.vd;
    unseenInput(s, sd);
    if (dead) {
      if (s > thr) {
        // passes
      } else {
        s = thr;
        sd = 0.0;
      }
    }
    if (lag) {
      if (rest) x[kP] = s;
      d[kP] = std::clamp((s - x[kP]) / lag_tau, -lag_slew, lag_slew);
      s = x[kP];
      sd = d[kP];
    } else if (dlag || vflow) {
      if (rest) x[kP] = s;
      d[kP] = unseenLagRate(s, x[kP]);
      s = x[kP];
      sd = d[kP];
    }
    // Core.
    const double h = x[kH];
    d[kH] = c.alpha * sd - c.beta * sd * std::fabs(h) - c.gamma * std::fabs(sd) * h;
    double y = c.k * c.rho * s + c.b + c.k * (1.0 - c.rho) * h;
    double yd = c.k * c.rho * sd + c.k * (1.0 - c.rho) * d[kH];
    // Output stage.
    if (asym) {
      const double z = x[kZa];
      d[kZa] = sd > 0.0 ? sd * (1.0 - z / as_wu) : sd < 0.0 ? sd * (1.0 + z / as_wd) : 0.0;
      y += as_gain * z;
      yd += as_gain * d[kZa];
    }
    if (load) {
      y -= compliance * dr.L;
      yd -= compliance * dr.Ld;
    }
    if (sat && y > knee) {
      const double th = std::tanh((y - knee) / width);
      y = knee + width * th;
      yd *= 1.0 - th * th;
    }
    if (creep) {
      if (rest) x[kZc] = cr_frac * y;
      d[kZc] = (cr_frac * y - x[kZc]) / cr_tau;
      y += x[kZc];
      yd += d[kZc];
    }
    if (fric && fr_zmax > 0.0) {
      const double a = fr_zmax / fr_delta;
      const double g = std::max(0.0, 1.0 - sgn(yd) * x[kZf] / fr_zmax);
      d[kZf] = a * g * yd / (1.0 + a * g);
      y -= x[kZf];
      yd -= d[kZf];
    }
    if (mass || floop) {
      if (rest) x[kX] = y;
      double force = y - x[kX];
      if (floop && fl_zmax > 0.0) {
        const double g = std::max(0.0, 1.0 - sgn(x[kXd]) * x[kZl] / fl_zmax);
        d[kZl] = fl_zmax / fl_delta * g * x[kXd];
        force -= x[kZl];
      }
      d[kX] = x[kXd];
      d[kXd] = wn * wn * force - 2.0 * zeta * wn * x[kXd];
      y = x[kX];
      yd = x[kXd];
    }
    if (mb) {
      if (rest) {
        x[kX] = bal.rest(y);
        for (int i = 0; i < kSlipElements; ++i) x[kE0 + i] = x[kX];
      }
      y = bal.rates(x, y, wn, zeta, d);
      yd = d[kX];
    }
    if (pb) {  // the balance driven by the pressure p, which the regulator moves towards the setpoint y
      if (rest) {
        x[kPr] = std::clamp(y, -air.w, air.supply - air.w);  // between the atmosphere and the supply
        x[kX] = bal.rest(x[kPr]);
        for (int i = 0; i < kSlipElements; ++i) x[kE0 + i] = x[kX];
      }
      const double p = x[kPr];
      const double setpoint = y;
      y = bal.rates(x, p, wn, zeta, d);
      d[kPr] = air.pressureRate(setpoint, p, x[kX], d[kX]);
      yd = d[kX];
    }
    if (warm) {
      const double phi = -std::expm1(-t / wu_tau);
      y += phi * (wu_gain * (y - y_start) + wu_shift);
    }
    if (dx) *dx = d;
    return y;
  }
};

Balance balanceOf(const EffectSpec& e) {
  Balance b;
  b.w = param(e, "w"), b.L = param(e, "L"), b.f0 = param(e, "f0"), b.fp = param(e, "fp");
  b.k_slip = param(e, "k_slip"), b.spread = param(e, "spread"), b.lo = param(e, "lo"), b.hi = param(e, "hi");
  b.fg = param(e, "fg"), b.vg = param(e, "vg");
  return b;
}

System makeSystem(const Core& core, const std::vector<EffectSpec>& effects, const SimOptions& opt) {
  validateEffects(effects);
  System s;
  s.c = core;
  s.tv = opt.valve_tau;
  for (const auto& e : effects) {
    const std::string& n = e.name;
    if (n == "delay")
      s.delay = param(e, "d");
    else if (n == "dead_band")
      s.dead = true, s.thr = param(e, "threshold");
    else if (n == "pressure_lag")
      s.lag = true, s.lag_tau = param(e, "tau"), s.lag_slew = param(e, "slew");
    else if (n == "asymmetry")
      s.asym = true, s.as_gain = param(e, "gain"), s.as_wu = param(e, "w_up"), s.as_wd = param(e, "w_down");
    else if (n == "load")
      s.load = true, s.compliance = param(e, "compliance");
    else if (n == "saturation")
      s.sat = true, s.knee = param(e, "knee"), s.width = param(e, "width");
    else if (n == "creep")
      s.creep = true, s.cr_frac = param(e, "fraction"), s.cr_tau = param(e, "tau");
    else if (n == "friction_hysteresis")
      s.fric = true, s.fr_zmax = param(e, "zmax"), s.fr_delta = param(e, "delta");
    else if (n == "mass_spring")
      s.mass = true, s.wn = 2.0 * M_PI * param(e, "fn"), s.zeta = param(e, "zeta");
    else if (n == "force_loop")
      s.floop = true, s.wn = 2.0 * M_PI * param(e, "fn"), s.zeta = param(e, "zeta"), s.fl_zmax = param(e, "zmax"),
      s.fl_delta = param(e, "delta");
    else if (n == "muscle_balance")
      s.mb = true, s.wn = 2.0 * M_PI * param(e, "fn"), s.zeta = param(e, "zeta"), s.bal = balanceOf(e);
    else if (n == "pneumatic_balance")
      s.pb = true, s.wn = 2.0 * M_PI * param(e, "fn"), s.zeta = param(e, "zeta"), s.bal = balanceOf(e),
      s.air = pneumaticAir(e);
    else if (n == "warm_up")
      s.warm = true, s.wu_tau = param(e, "tau"), s.wu_gain = param(e, "gain"), s.wu_shift = param(e, "shift");
    else if (n == "dead_zone")
      s.dz = true, s.dz_c = param(e, "centre"), s.dz_w = param(e, "width");
    else if (n == "piecewise_gain")
      s.pwg = true, s.pw_knee = param(e, "knee"), s.pw_gain = param(e, "gain");
    else if (n == "input_saturation")
      s.isat = true, s.is_lo = param(e, "lo"), s.is_hi = param(e, "hi");
    else if (n == "direction_lag")
      s.dlag = true, s.tau_up = param(e, "tau_up"), s.tau_down = param(e, "tau_down");
    else if (n == "valve_flow")
      s.vflow = true, s.vf_rate = param(e, "rate"), s.vf_eps = param(e, "eps");
  }
  return s;
}

// The output stage outside the catalogue, applied to each clean sample in turn (rate-independent
// operators and an additive vibration): play hysteresis of the command, backlash, periodic disturbance.
class OutputStage {
 public:
  explicit OutputStage(const std::vector<EffectSpec>& effects) {
    for (const auto& e : effects) {
      if (e.name == "play_hysteresis")
        for (int i = 1; i <= 3; ++i)
          plays_.push_back({param(e, "r" + std::to_string(i)), param(e, "w" + std::to_string(i)), 0.0, false});
      if (e.name == "backlash") backlash_ = true, bl_w_ = param(e, "width");
      if (e.name == "periodic_disturbance")
        per_ = true, per_a_ = param(e, "amplitude"), per_f_ = param(e, "freq"),
        per_ph_ = param(e, "phase") * M_PI / 180;
    }
  }
  double step(double t_end, double u, double y) {
    for (auto& p : plays_) {
      if (!p.started) p.x = u, p.started = true;
      p.x = std::clamp(p.x, u - p.r, u + p.r);
      y += p.w * p.x;
    }
    if (backlash_) {
      if (!bl_started_) bl_x_ = y, bl_started_ = true;
      bl_x_ = std::clamp(bl_x_, y - bl_w_ / 2, y + bl_w_ / 2);
      y = bl_x_;
    }
    if (per_) y += per_a_ * std::sin(2 * M_PI * per_f_ * t_end + per_ph_);
    return y;
  }

 private:
  struct Play {
    double r, w, x;
    bool started;
  };
  std::vector<Play> plays_;
  bool backlash_ = false, bl_started_ = false, per_ = false;
  double bl_w_ = 0, bl_x_ = 0, per_a_ = 0, per_f_ = 0, per_ph_ = 0;
};

// Dormand-Prince RK5(4)7M with first-same-as-last and an elementary step-size controller, integrating
// over one interval on which the held inputs do not change.
class Integrator {
 public:
  Integrator(const System& sys, const SimOptions& opt) : sys_(sys), opt_(opt), h_(opt.max_step) {}

  // Integrates x from t0 to t1 with command uc and load Lc held; `jump` says the inputs changed at t0.
  // The valve stage and the load's first-order stage are linear and their inputs held, so they move by
  // their closed form v(t) = uc + (v(t0) - uc) exp(-(t - t0) / tau_v): the stiff fast pole never meets
  // the explicit integrator, which integrates the rest with v(t) and v'(t) as known functions of time.
  void run(Vec& x, double t0, double t1, double uc, double Lc, bool jump) {
    if (!(t1 > t0)) return;
    if (jump) h_ = std::min(h_, 0.05 * sys_.tv);
    const double ev = x[kV] - uc, eL = x[kL] - Lc;
    auto drive = [&](double tc) {
      const double E = std::exp(-(tc - t0) / sys_.tv);
      return Drive{uc + ev * E, -ev * E / sys_.tv, Lc + eL * E, -eL * E / sys_.tv};
    };
    Vec k1, k2, k3, k4, k5, k6, k7, tmp, xn;
    sys_.eval(t0, x, drive(t0), &k1, false);
    double t = t0;
    while (t < t1) {
      const double hp = std::min(h_, opt_.max_step);
      double h = hp;
      bool last = false;
      if (t + h >= t1 - 1e-12 * std::max(1.0, std::fabs(t1))) {  // no sliver left at the end
        h = t1 - t;
        last = true;
      }
      auto stage = [&](Vec& out, double tc, std::initializer_list<std::pair<const Vec*, double>> terms) {
        for (int i = 0; i < kN; ++i) {
          double acc = x[i];
          for (const auto& [kv, a] : terms) acc += h * a * (*kv)[i];
          tmp[i] = acc;
        }
        sys_.eval(tc, tmp, drive(tc), &out, false);
      };
      stage(k2, t + h / 5, {{&k1, 1.0 / 5}});
      stage(k3, t + 3 * h / 10, {{&k1, 3.0 / 40}, {&k2, 9.0 / 40}});
      stage(k4, t + 4 * h / 5, {{&k1, 44.0 / 45}, {&k2, -56.0 / 15}, {&k3, 32.0 / 9}});
      stage(k5, t + 8 * h / 9,
            {{&k1, 19372.0 / 6561}, {&k2, -25360.0 / 2187}, {&k3, 64448.0 / 6561}, {&k4, -212.0 / 729}});
      stage(
          k6, t + h,
          {{&k1, 9017.0 / 3168}, {&k2, -355.0 / 33}, {&k3, 46732.0 / 5247}, {&k4, 49.0 / 176}, {&k5, -5103.0 / 18656}});
      for (int i = 0; i < kN; ++i)
        xn[i] = x[i] + h * (35.0 / 384 * k1[i] + 500.0 / 1113 * k3[i] + 125.0 / 192 * k4[i] - 2187.0 / 6784 * k5[i] +
                            11.0 / 84 * k6[i]);
      {
        const Drive dn = drive(t + h);
        xn[kV] = dn.v;
        xn[kL] = dn.L;
        sys_.eval(t + h, xn, dn, &k7, false);
      }
      double err = 0.0;
      for (int i = 0; i < kN; ++i) {
        const double e = h * (71.0 / 57600 * k1[i] - 71.0 / 16695 * k3[i] + 71.0 / 1920 * k4[i] -
                              17253.0 / 339200 * k5[i] + 22.0 / 525 * k6[i] - 1.0 / 40 * k7[i]);
        const double sc = opt_.atol + opt_.rtol * std::max(std::fabs(x[i]), std::fabs(xn[i]));
        err = std::max(err, std::fabs(e) / sc);
      }
      if (err <= 1.0 || h < 1e-14) {
        if (sys_.mb || sys_.pb) {
          const double f = sys_.bal.eventFraction(x, xn);
          if (f < 1.0 && h * f > 1e-14) {  // the step cut where the payload turns round or meets a stop
            h_ = h * f;
            continue;
          }
          if (sys_.bal.settle(xn)) sys_.eval(t + h, xn, drive(t + h), &k7, false);
        }
        t = last ? t1 : t + h;
        x = xn;
        k1 = k7;
        ++steps_;
        const double hn = h * std::clamp(err > 0.0 ? 0.9 * std::pow(err, -0.2) : 5.0, 0.2, 5.0);
        // A last step cut short to end on t1 does not shrink the step carried on.
        h_ = last && hn >= h ? std::max(hn, hp) : hn;
      } else {
        ++rejected_;
        h_ = h * std::clamp(0.9 * std::pow(err, -0.2), 0.1, 0.9);
      }
    }
  }
  long steps() const { return steps_; }
  long rejected() const { return rejected_; }
  // As constructed: the first step at the largest, the statistics at 0.
  void restart() {
    h_ = opt_.max_step;
    steps_ = rejected_ = 0;
  }

 private:
  const System& sys_;
  SimOptions opt_;
  double h_;
  long steps_ = 0, rejected_ = 0;
};

double uniform01(std::mt19937_64& g) { return static_cast<double>(g() >> 11) * 0x1.0p-53; }

// Box-Muller on the generator's own bits (std::normal_distribution differs between libraries).
double gauss(std::mt19937_64& g) {
  double u1 = uniform01(g);
  while (u1 <= 0.0) u1 = uniform01(g);
  const double u2 = uniform01(g);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace

// The stepped chain: the system, its integrator, the delay's history of commands, the output stage
// and the noise generator. Heap-held by Stepper (the integrator keeps a reference to the system).
struct Stepper::Impl {
  Impl(const Core& core, const std::vector<EffectSpec>& effects, const SimOptions& o)
      : opt(o), sys(makeSystem(core, effects, o)), integ(sys, o), out(effects), effects_(effects) {
    const double dn = sys.delay / opt.Ts;
    nd = static_cast<long>(std::floor(dn + 1e-9));
    frac = dn - static_cast<double>(nd);
    if (frac < 1e-9) frac = 0.0;
    hist.assign(static_cast<size_t>(nd + 2), 0.0);
  }
  // The command held in sample j (the first command before the start).
  double cmd(long j) const { return j < 0 ? u0 : hist[static_cast<size_t>(j % static_cast<long>(hist.size()))]; }
  // Integrates over sample k with its command in the history and the load L held.
  void integrate(double L) {
    const double t0 = static_cast<double>(k) * opt.Ts, t1 = static_cast<double>(k + 1) * opt.Ts;
    if (frac == 0.0) {
      const double uc = cmd(k - nd);
      integ.run(x, t0, t1, uc, L, uc != prev_u || L != prev_L);
      prev_u = uc;
    } else {  // the delayed command switches within the sample at t0 + frac Ts
      const double tm = t0 + frac * opt.Ts;
      const double ua = cmd(k - nd - 1), ub = cmd(k - nd);
      integ.run(x, t0, tm, ua, L, ua != prev_u || L != prev_L);
      integ.run(x, tm, t1, ub, L, ub != ua);
      prev_u = ub;
    }
    prev_L = L;
  }

  SimOptions opt;
  System sys;
  Integrator integ;
  OutputStage out;
  std::vector<EffectSpec> effects_;
  Vec x{};
  long nd = 0, k = 0;
  double frac = 0.0, u0 = 0.0, prev_u = 0.0, prev_L = 0.0, clean = 0.0;
  std::vector<double> hist;
  std::mt19937_64 g;
};

Stepper::Stepper(const Core& core, const std::vector<EffectSpec>& effects, const SimOptions& opt) {
  if (!(opt.Ts > 0) || !(opt.valve_tau > 0) || !(opt.rtol > 0) || !(opt.atol > 0) || !(opt.max_step > 0) ||
      !(opt.noise_std >= 0) || !(opt.quantum >= 0))
    throw std::invalid_argument("bad simulation options");
  impl_ = std::make_unique<Impl>(core, effects, opt);
  reset(0.0, 0.0);
}

Stepper::~Stepper() = default;

void Stepper::reset(double u0, double load0) {
  Impl& m = *impl_;
  const double L = m.sys.load ? load0 : 0.0;
  m.integ.restart();
  m.out = OutputStage(m.effects_);
  m.x = Vec{};
  m.sys.y_start = m.sys.eval(0.0, m.x, Drive{u0, 0.0, L, 0.0}, nullptr, true);  // warm_up adds phi(0) = 0 here
  m.clean = m.sys.y_start;
  m.k = 0;
  m.u0 = m.prev_u = u0;
  m.prev_L = L;
  std::fill(m.hist.begin(), m.hist.end(), u0);
  m.g.seed(m.opt.noise_seed);
}

double Stepper::step(double u, double load) {
  Impl& m = *impl_;
  if (!std::isfinite(u)) throw std::invalid_argument("command not finite");
  const double L = m.sys.load ? load : 0.0;
  m.hist[static_cast<size_t>(m.k % static_cast<long>(m.hist.size()))] = u;
  m.integrate(L);
  const double t1 = static_cast<double>(m.k + 1) * m.opt.Ts;
  const Drive dr{m.x[kV], (m.prev_u - m.x[kV]) / m.sys.tv, m.x[kL], (L - m.x[kL]) / m.sys.tv};
  m.clean = m.out.step(t1, u, m.sys.eval(t1, m.x, dr, nullptr, false));
  ++m.k;
  double y = m.clean + (m.opt.noise_std > 0 ? m.opt.noise_std * gauss(m.g) : 0.0);
  if (m.opt.quantum > 0) y = std::round(y / m.opt.quantum) * m.opt.quantum;
  return y;
}

bool Stepper::needsLoad() const { return impl_->sys.load; }
double Stepper::clean() const { return impl_->clean; }
double Stepper::pressure() const { return impl_->sys.pb ? impl_->x[kPr] : std::nan(""); }
long Stepper::steps() const { return impl_->integ.steps(); }
long Stepper::rejected() const { return impl_->integ.rejected(); }

Record simulate(const Core& core, const std::vector<EffectSpec>& effects, const std::vector<double>& u,
                const std::vector<double>* load, const SimOptions& opt) {
  if (u.empty()) throw std::invalid_argument("empty command");
  const bool has_load = load && !load->empty();
  if (has_load && load->size() != u.size()) throw std::invalid_argument("load column and command differ in length");
  for (double v : u)
    if (!std::isfinite(v)) throw std::invalid_argument("command not finite");
  Stepper st(core, effects, opt);
  if (st.needsLoad() && !has_load) throw std::invalid_argument("effect load needs a load column (--load SPEC)");
  const size_t n = u.size();
  auto Lat = [&](size_t k) { return has_load ? (*load)[k] : 0.0; };

  Record r;
  r.Ts = opt.Ts;
  r.noise_std = opt.noise_std;
  r.quantum = opt.quantum;
  r.t.resize(n);
  r.u = u;
  r.y.resize(n);
  r.y_clean.resize(n);
  if (has_load) r.load = *load;
  st.reset(u[0], Lat(0));
  for (size_t k = 0; k < n; ++k) {
    r.t[k] = static_cast<double>(k) * opt.Ts;
    r.y[k] = st.step(u[k], Lat(k));
    r.y_clean[k] = st.clean();
  }
  r.steps = st.steps();
  r.rejected = st.rejected();
  return r;
}

// ---------------------------------------------------------------------------------------------
// Excitations.

namespace {

struct Segment {
  std::string kind;
  std::map<std::string, double> p;
  double dur = -1.0;  // seconds; < 0: a share of the rest
};

const std::map<std::string, std::vector<std::string>>& segmentKeys() {
  static const std::map<std::string, std::vector<std::string>> k = {
      {"steps", {"lo", "hi", "min", "max"}},
      {"chirp", {"f0", "f1", "lo", "hi"}},
      {"sine", {"f", "lo", "hi", "phase"}},
      {"triangle", {"f", "lo", "hi"}},
      {"multisine", {"fmin", "fmax", "n", "lo", "hi"}},
      {"hold", {"level"}},
      {"ramp", {"from", "to"}},
      {"mixed", {"lo", "hi"}},
  };
  return k;
}

double get(const Segment& s, const std::string& key, double def) {
  auto it = s.p.find(key);
  return it == s.p.end() ? def : it->second;
}

// Appends n samples of the segment.
void generate(const Segment& s, size_t n, double Ts, std::mt19937_64& g, std::vector<double>& out) {
  const double lo = get(s, "lo", -3.0), hi = get(s, "hi", 3.0);
  if (!(hi >= lo)) throw std::invalid_argument(s.kind + ": hi below lo");
  const double mid = 0.5 * (lo + hi), amp = 0.5 * (hi - lo);
  const double T = static_cast<double>(n) * Ts;
  if (s.kind == "steps") {
    const double mn = get(s, "min", 0.3), mx = get(s, "max", 3.0);
    if (!(mn > 0) || !(mx >= mn)) throw std::invalid_argument("steps: need 0 < min <= max");
    size_t i = 0;
    while (i < n) {
      const double level = lo + (hi - lo) * uniform01(g);
      const double held = mn + (mx - mn) * uniform01(g);
      const size_t m = std::max<size_t>(1, static_cast<size_t>(std::llround(held / Ts)));
      for (size_t j = 0; j < m && i < n; ++j, ++i) out.push_back(level);
    }
  } else if (s.kind == "chirp") {
    const double f0 = get(s, "f0", 0.05), f1 = get(s, "f1", 5.0);
    if (!(f0 >= 0) || !(f1 >= 0)) throw std::invalid_argument("chirp: frequencies must be >= 0");
    for (size_t i = 0; i < n; ++i) {
      const double t = static_cast<double>(i) * Ts;
      out.push_back(mid + amp * std::sin(2.0 * M_PI * (f0 * t + (f1 - f0) * t * t / (2.0 * T))));
    }
  } else if (s.kind == "sine") {
    const double f = get(s, "f", 0.1), ph = get(s, "phase", 0.0) * M_PI / 180.0;
    if (!(f > 0)) throw std::invalid_argument("sine: f must be > 0");
    for (size_t i = 0; i < n; ++i)
      out.push_back(mid + amp * std::sin(2.0 * M_PI * f * static_cast<double>(i) * Ts + ph));
  } else if (s.kind == "triangle") {
    const double f = get(s, "f", 0.05);
    if (!(f > 0)) throw std::invalid_argument("triangle: f must be > 0");
    for (size_t i = 0; i < n; ++i) {
      const double ph = std::fmod(f * static_cast<double>(i) * Ts, 1.0);
      out.push_back(lo + (hi - lo) * (ph < 0.5 ? 2.0 * ph : 2.0 - 2.0 * ph));
    }
  } else if (s.kind == "multisine") {
    const double fmin = get(s, "fmin", 0.02), fmax = get(s, "fmax", 2.0);
    const double nf = get(s, "n", 20);
    if (!(fmin > 0) || !(fmax >= fmin) || !(nf >= 1 && nf <= 1000))
      throw std::invalid_argument("multisine: need 0 < fmin <= fmax and 1 <= n <= 1000");
    const int m = static_cast<int>(nf);
    std::vector<double> f(static_cast<size_t>(m)), phase(static_cast<size_t>(m));
    for (int j = 0; j < m; ++j) {
      // log-spaced, random phases
      f[static_cast<size_t>(j)] = m == 1 ? fmin : fmin * std::pow(fmax / fmin, static_cast<double>(j) / (m - 1));
      phase[static_cast<size_t>(j)] = 2.0 * M_PI * uniform01(g);
    }
    std::vector<double> raw(n);
    double peak = 0.0;
    for (size_t i = 0; i < n; ++i) {
      double acc = 0.0;
      for (int j = 0; j < m; ++j)
        acc += std::sin(2.0 * M_PI * f[static_cast<size_t>(j)] * static_cast<double>(i) * Ts +
                        phase[static_cast<size_t>(j)]);
      raw[i] = acc;
      peak = std::max(peak, std::fabs(acc));
    }
    for (size_t i = 0; i < n; ++i) out.push_back(mid + amp * (peak > 0 ? raw[i] / peak : 0.0));
  } else if (s.kind == "hold") {
    const double level = get(s, "level", 0.0);
    out.insert(out.end(), n, level);
  } else if (s.kind == "ramp") {
    const double a = get(s, "from", 0.0), b = get(s, "to", 3.0);
    for (size_t i = 0; i < n; ++i)
      out.push_back(n > 1 ? a + (b - a) * static_cast<double>(i) / static_cast<double>(n - 1) : a);
  } else if (s.kind == "mixed") {
    // steps 35 %, hold 7.5 %, chirp 25 %, sine 0.1 Hz 12.5 %, sine 0.3 Hz 12.5 %, hold 7.5 %.
    const double shares[6] = {0.35, 0.075, 0.25, 0.125, 0.125, 0.075};
    size_t done = 0;
    double cum = 0.0;
    for (int j = 0; j < 6; ++j) {
      cum += shares[j];
      const size_t end = j == 5 ? n : static_cast<size_t>(std::llround(cum * static_cast<double>(n)));
      const size_t m = end - done;
      Segment sub;
      sub.p["lo"] = lo;
      sub.p["hi"] = hi;
      if (j == 0) sub.kind = "steps";
      if (j == 1 || j == 5) {
        sub.kind = "hold";
        sub.p.clear();
        sub.p["level"] = lo + (hi - lo) * uniform01(g);
      }
      if (j == 2) sub.kind = "chirp", sub.p["f0"] = 0.05, sub.p["f1"] = 3.0;
      if (j == 3) sub.kind = "sine", sub.p["f"] = 0.1;
      if (j == 4) sub.kind = "sine", sub.p["f"] = 0.3;
      generate(sub, m, Ts, g, out);
      done = end;
    }
  } else {
    throw std::invalid_argument("unknown excitation '" + s.kind + "'");
  }
}

}  // namespace

std::vector<double> makeSignal(const std::string& spec, double duration, double Ts, std::uint64_t seed) {
  if (!(duration > 0) || !(Ts > 0) || duration / Ts > 1e8) throw std::invalid_argument("bad duration or sample time");
  std::vector<Segment> segs;
  if (trim(spec).empty()) throw std::invalid_argument("empty excitation spec");
  for (const auto& part : split(spec, '+')) {
    Segment s;
    const auto colon = part.find(':');
    s.kind = trim(part.substr(0, colon));
    auto keys = segmentKeys().find(s.kind);
    if (keys == segmentKeys().end()) {
      std::string known;
      for (const auto& [k, v] : segmentKeys()) (void)v, known += (known.empty() ? "" : ", ") + k;
      throw std::invalid_argument("unknown excitation '" + s.kind + "' (known: " + known + ")");
    }
    if (colon != std::string::npos) s.p = parseKeyValues(part.substr(colon + 1), "excitation " + s.kind);
    for (const auto& [k, v] : s.p) {
      if (k == "dur") {
        if (!(v > 0)) throw std::invalid_argument("excitation " + s.kind + ": dur must be > 0");
        s.dur = v;
        continue;
      }
      if (std::find(keys->second.begin(), keys->second.end(), k) == keys->second.end())
        throw std::invalid_argument("excitation " + s.kind + " has no key '" + k + "'");
    }
    s.p.erase("dur");
    segs.push_back(s);
  }
  double fixed = 0.0;
  int shared = 0;
  for (const auto& s : segs) {
    if (s.dur > 0)
      fixed += s.dur;
    else
      ++shared;
  }
  if (fixed > duration + 1e-9) throw std::invalid_argument("excitation segments last longer than the duration");
  const double each = shared ? (duration - fixed) / shared : 0.0;
  const size_t total = static_cast<size_t>(std::llround(duration / Ts));
  std::vector<double> out;
  out.reserve(total);
  std::mt19937_64 g(seed);
  double cum = 0.0;
  for (size_t j = 0; j < segs.size(); ++j) {
    cum += segs[j].dur > 0 ? segs[j].dur : each;
    const size_t end =
        j + 1 == segs.size() && shared ? total : std::min(total, static_cast<size_t>(std::llround(cum / Ts)));
    if (end > out.size()) generate(segs[j], end - out.size(), Ts, g, out);
  }
  if (out.size() < total) out.insert(out.end(), total - out.size(), out.empty() ? 0.0 : out.back());
  if (out.empty()) throw std::invalid_argument("excitation has no samples");
  return out;
}

// ---------------------------------------------------------------------------------------------
// Cases.

std::string defaultCasesPath() {
#ifdef PAMC_ORACLE_CASES
  return PAMC_ORACLE_CASES;
#else
  return "tests/oracle/cases.json";
#endif
}

namespace {

RecordSpec parseRecordSpec(const nlohmann::json& j, const std::string& where) {
  RecordSpec r;
  if (!j.is_object()) throw std::runtime_error(where + ": expected an object");
  for (const auto& [k, v] : j.items()) {
    if (k == "input")
      r.input = v.get<std::string>();
    else if (k == "load")
      r.load = v.get<std::string>();
    else if (k == "duration")
      r.duration = v.get<double>();
    else if (k == "seed")
      r.seed = v.get<std::uint64_t>();
    else
      throw std::runtime_error(where + ": unknown key '" + k + "'");
  }
  if (r.input.empty()) throw std::runtime_error(where + ": missing input");
  if (!(r.duration > 0)) throw std::runtime_error(where + ": duration must be > 0");
  return r;
}

}  // namespace

std::vector<Case> loadCases(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  std::vector<Case> out;
  try {
    std::set<std::string> names;
    for (const auto& cj : j.at("cases")) {
      Case c;
      c.name = cj.at("name").get<std::string>();
      const std::string where = path + ": case " + c.name;
      if (!names.insert(c.name).second) throw std::runtime_error(where + ": name used twice");
      c.description = cj.value("description", "");
      if (cj.contains("core")) {
        std::string text;
        for (const auto& [k, v] : cj.at("core").items()) {
          std::ostringstream os;
          os.precision(17);
          os << k << "=" << v.get<double>();
          text += (text.empty() ? "" : ",") + os.str();
        }
        c.core = parseCore(text);
      }
      if (cj.contains("effects")) {
        for (const auto& [name, pj] : cj.at("effects").items()) {
          std::string text = name;
          std::string kv;
          for (const auto& [k, v] : pj.items()) {
            std::ostringstream os;
            os.precision(17);
            os << k << "=" << v.get<double>();
            kv += (kv.empty() ? "" : ",") + os.str();
          }
          if (!kv.empty()) text += ":" + kv;
          c.effects.push_back(parseEffect(text));
        }
      }
      validateEffects(c.effects);
      c.noise_std = cj.value("noise", 0.005);
      c.train = parseRecordSpec(cj.at("train"), where + " train");
      c.validate = parseRecordSpec(cj.at("validate"), where + " validate");
      c.expected = cj.at("expected").get<std::vector<std::string>>();
      out.push_back(c);
    }
  } catch (const std::runtime_error&) {
    throw;
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  return out;
}

Record makeCaseRecord(const Case& c, const std::string& which, SimOptions opt) {
  if (which != "train" && which != "validate")
    throw std::invalid_argument("record must be train or validate, not '" + which + "'");
  const RecordSpec& r = which == "train" ? c.train : c.validate;
  const std::vector<double> u = makeSignal(r.input, r.duration, opt.Ts, r.seed);
  std::vector<double> load;
  if (!r.load.empty()) load = makeSignal(r.load, r.duration, opt.Ts, r.seed ^ 0x5bd1e995ULL);
  opt.noise_std = c.noise_std;
  opt.noise_seed = r.seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL;
  return simulate(c.core, c.effects, u, load.empty() ? nullptr : &load, opt);
}

void writeRecordCsv(const std::string& path, const Record& r) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "w");
  if (!f) throw std::runtime_error(tmp + ": cannot write");
  const bool with_load = !r.load.empty();
  bool ok = std::fputs(with_load ? "t,u,y,load\n" : "t,u,y\n", f) >= 0;
  for (size_t k = 0; ok && k < r.t.size(); ++k) {
    if (with_load)
      ok = std::fprintf(f, "%.6f,%.9g,%.9g,%.9g\n", r.t[k], r.u[k], r.y[k], r.load[k]) > 0;
    else
      ok = std::fprintf(f, "%.6f,%.9g,%.9g\n", r.t[k], r.u[k], r.y[k]) > 0;
  }
  ok = std::fflush(f) == 0 && ok;
  ok = std::fclose(f) == 0 && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": write failed");
  }
}

}  // namespace pamc::oracle
