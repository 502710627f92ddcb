#include "ident/identify.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <thread>

#include "io/text.hpp"
#include "model/staged_simulation.hpp"

namespace pamc::ident {

namespace {
double range(const std::vector<double>& v) {
  const auto [a, b] = std::minmax_element(v.begin(), v.end());
  return *b - *a;
}

// A record rests on a stop at an extreme of its output (recordRests) where at least kRestShare of its
// samples lie within kRestBand of the range from that extreme (chosen: records of the physics plant that
// lie on a stop hold 3.8-4.4 % of their samples there, those that only turn at their extreme 0.02-0.04 %;
// the oracle's whole-stroke case touches its top stop with 0.6 %, and a first choice of 1 % lost that
// stop), while the input moves on over at least kRestInput of its range: a stop holds the output whatever
// the input does past it, a slow sine's turn holds it only while the input turns too (chosen: the physics
// plant's and the oracle's records on a stop move the input over 5.7-91 % of its range there, the paper's
// u0 and u1 over 0.6-2.0 % at their turns - which hold 0.2-2.1 % of their samples, a share like a stop's).
constexpr double kRestShare = 0.002;
constexpr double kRestBand = 0.002;
constexpr double kRestInput = 0.035;
struct Rest {
  size_t n = 0;
  double ulo = std::numeric_limits<double>::infinity(), uhi = -std::numeric_limits<double>::infinity();
  void add(double u) { ++n, ulo = std::min(ulo, u), uhi = std::max(uhi, u); }
  ExtremeRest judge(size_t samples, double ru) const {
    ExtremeRest r;
    r.share = samples > 0 ? static_cast<double>(n) / static_cast<double>(samples) : 0.0;
    r.input_moved = n > 0 ? (uhi - ulo) / ru : 0.0;
    const auto need = static_cast<size_t>(std::ceil(kRestShare * static_cast<double>(samples)));
    r.on_stop = n > 0 && n >= need && uhi - ulo >= kRestInput * ru;
    return r;
  }
};
std::string percent(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f %%", 100.0 * x);
  return b;
}
std::string describeRest(const char* which, const ExtremeRest& r) {
  return std::string("at its ") + which + " output " + (r.on_stop ? "it rests on a stop" : "it does not rest") + " (" +
         percent(r.share) + " of the samples within " + percent(kRestBand) +
         " of the output's range, the input moving over " + percent(r.input_moved) + " of its range there)";
}

// recordRests with the record's output extremes and input range already at hand (dataBounds has them).
RecordRests restsWithin(const io::Measurement& d, double ymin, double ymax, double ru) {
  const double band = kRestBand * (ymax - ymin);
  Rest low, high;
  for (size_t i = 0; i < d.y.size(); ++i) {
    if (d.y[i] <= ymin + band) low.add(d.u[i]);
    if (d.y[i] >= ymax - band) high.add(d.u[i]);
  }
  return {low.judge(d.y.size(), ru), high.judge(d.y.size(), ru)};
}
}  // namespace

RecordRests recordRests(const io::Measurement& d) {
  if (d.y.empty() || d.u.empty()) return {};
  const auto [ymin, ymax] = std::minmax_element(d.y.begin(), d.y.end());
  return restsWithin(d, *ymin, *ymax, std::max(range(d.u), 1e-12));
}

std::string describeRests(const RecordRests& r) {
  return "end stops (a fit searches a stop within the record only where it rests on one: at least " +
         percent(kRestShare) + " of the samples, the input moving over at least " + percent(kRestInput) +
         " of its range): " + describeRest("lowest", r.low) + "; " + describeRest("highest", r.high);
}

Bounds dataBounds(const model::Model& m, const io::Measurement& d) {
  const auto specs = m.paramSpecs();
  Bounds b;
  for (const auto& s : specs) {
    b.lo.push_back(s.lo);
    b.hi.push_back(s.hi);
  }
  const double ru = std::max(range(d.u), 1e-12);
  const double ry = std::max(range(d.y), 1e-12);
  const auto [ymin, ymax] = std::minmax_element(d.y.begin(), d.y.end());
  double umax = 0;
  for (double u : d.u) umax = std::max(umax, std::fabs(u));
  // The search runs over a = k rho and c = k (1 - rho) - the gains of u and of h in the output,
  // which the data bound directly - instead of (k, rho), whose product couples them.
  // With alpha fixed at +1 a lagging (counter-clockwise) loop has c < 0 (see bouc_wen.hpp).
  double reach = 1.0;
  for (int i = 0; i < m.numEffects(); ++i) reach = std::max(reach, m.effect(i).coreReach());
  const double kmax = 4.0 * reach * ry / ru;
  b.lo[0] = -kmax;
  b.hi[0] = kmax;  // a = k rho
  b.lo[1] = -10.0 * ry / ru;
  b.hi[1] = 10.0 * ry / ru;  // c = k (1 - rho)
  b.lo[2] = *ymin - kmax * umax - ry;
  b.hi[2] = *ymax + kmax * umax + ry;  // b
  b.lo[3] = b.hi[3] = 1.0;             // alpha fixed: scale of h
  b.lo[4] = -10.0 / ru;
  b.hi[4] = 10.0 / ru;  // beta
  b.lo[5] = -10.0 / ru;
  b.hi[5] = 10.0 / ru;  // gamma
  // Effect parameters: the catalogue's bounds are written for a 40 mm / 10 V rig at 1 kHz; scale
  // them to this data by their unit so any units and sample rate work.
  const double duration = d.Ts * static_cast<double>(d.size());
  const auto rests = restsWithin(d, *ymin, *ymax, ru);
  const auto [umin, umax_] = std::minmax_element(d.u.begin(), d.u.end());
  const auto* load = d.column("load");
  const double rl = load ? std::max(range(*load), 1e-12) : 1.0;
  for (size_t i = model::kBoucWenParams; i < specs.size(); ++i) {
    const std::string& u = specs[i].unit;
    double& lo = b.lo[i];
    double& hi = b.hi[i];
    if (u == "y-unit") {
      lo *= ry / 40.0;
      hi *= ry / 40.0;
    } else if (u == "1/y-unit") {
      lo *= 40.0 / ry;
      hi *= 40.0 / ry;
    } else if (u == "1/y-unit^2") {
      lo *= (40.0 / ry) * (40.0 / ry);
      hi *= (40.0 / ry) * (40.0 / ry);
    } else if (u == "y-level") {
      // A level outside the data's range is indistinguishable from no effect (flat cost).
      lo = *ymin;
      hi = *ymax;
    } else if (u == "y-stop") {
      // An end stop: at the record's extreme where the record rests on it, else a range beyond it. A stop
      // the record never reaches is none; kept within the data it clipped the model at the record's
      // extreme (the calibrated physics plant's whole-stroke record turns at 33.1 mm, its validation
      // record goes on to 35.05: muscle_balance validated 0.65 mm with its stop there, 0.22 mm without).
      lo = rests.low.on_stop ? *ymin : *ymin - ry;
      hi = rests.high.on_stop ? *ymax : *ymax + ry;
    } else if (u == "u-unit") {
      lo *= ru / 10.0;
      hi *= ru / 10.0;
    } else if (u == "u-level") {
      lo = *umin;
      hi = *umax_;
    } else if (u == "u-unit/s") {
      lo *= ru / 10.0;
      hi *= ru / 10.0;
    } else if (u == "y-unit/u-unit") {
      lo *= ry / ru / 4.0;
      hi *= ry / ru / 4.0;
    } else if (u == "y-unit/load-unit") {
      lo = -2.0 * ry / rl;
      hi = 2.0 * ry / rl;
    } else if (u == "s") {
      // No faster than a few samples; no slower than the record; a delay at most the ring's length.
      lo = std::max(lo, specs[i].name.size() >= 2 && specs[i].name.compare(specs[i].name.size() - 2, 2, ".d") == 0
                            ? 0.0
                            : 2.0 * d.Ts);
      hi = std::min(hi, duration / 2.0);
      if (specs[i].name.size() >= 2 && specs[i].name.compare(specs[i].name.size() - 2, 2, ".d") == 0)
        hi = std::min(hi, 250.0 * d.Ts);
    } else if (u == "Hz") {
      lo = std::max(lo, 2.0 / duration);
      hi = std::min(hi, 0.2 / d.Ts);
    }
    if (hi < lo) hi = lo;
  }
  return b;
}

std::optional<model::Model> withWeakDefaults(const model::Model& m, const io::Measurement& d, std::string* names) {
  std::vector<std::string> held;
  std::string said;
  for (int e = 0; e < m.numEffects(); ++e) {
    const auto own = m.effect(e).weaklyHeld();
    for (size_t k = 0; k < own.size(); ++k) {
      held.push_back(std::string(m.effect(e).name()) + "." + own[k]);
      said += (k > 0 ? ", " : std::string(said.empty() ? "" : "; ") + m.effect(e).name() + "'s ") + own[k];
    }
  }
  if (held.empty()) return std::nullopt;
  const auto specs = m.paramSpecs();
  const Bounds box = dataBounds(m, d);
  auto p = m.params();
  for (size_t i = model::kBoucWenParams; i < specs.size(); ++i) {
    if (std::find(held.begin(), held.end(), specs[i].name) == held.end()) continue;
    const double scale = specs[i].hi != 0.0 ? box.hi[i] / specs[i].hi : 1.0;
    p[i] = std::clamp(specs[i].def * scale, box.lo[i], box.hi[i]);
  }
  model::Model r = m;
  r.setParams(p);
  if (names) *names = said;
  return r;
}

FitMethod fitMethodFromString(const std::string& s) {
  if (s == "ga") return FitMethod::Ga;
  if (s == "lm") return FitMethod::MultiStart;
  throw std::invalid_argument("unknown fit method '" + s + "' (ga, lm)");
}

const char* toString(FitMethod m) { return m == FitMethod::Ga ? "ga" : "lm"; }

FitMethod autoFitMethod(const model::Model& structure) {
  return structure.numEffects() == 0 ? FitMethod::MultiStart : FitMethod::Ga;
}

nlohmann::json fitReport(const FitResult& r, const FitSettings& s, const io::Measurement& data,
                         const std::string& source) {
  nlohmann::json j = {{"data", source},
                      {"samples", data.size()},
                      {"Ts", data.Ts},
                      {"rmse", r.rmse},
                      {"generations", r.generations},
                      {"evaluations", r.evaluations},
                      {"seconds", r.seconds},
                      {"seed", s.ga.seed},
                      {"method", toString(s.method)}};
  if (!r.widened.empty()) j["box_widened"] = r.widened;
  return j;
}

namespace {

// A scale that spans decades above zero: a travel from 0.01 to 20 mm, a time constant, a frequency.
bool spansDecades(double lo, double hi) { return lo > 0.0 && hi >= 100.0 * lo; }

// The warm starts: the start model with the new effects' parameters (explore) spread over their ranges
// (a Latin hypercube over them), so an effect whose cost is flat where the first start left it still
// gets a chance. Where one of them spans decades, as many starts again spread evenly in its logarithm:
// spread evenly in the value only, its shortest decades - a sharp friction, a fast lag - get almost no
// start (a 2 mm backlash taken by the friction: found by the second set only).
std::vector<std::vector<double>> warmStarts(const std::vector<double>& start, const std::vector<bool>& explore,
                                            const Bounds& b, int n, std::uint64_t seed) {
  std::vector<std::vector<double>> out;
  bool any_decades = false;
  for (size_t i = 0; i < start.size() && i < explore.size(); ++i)
    any_decades = any_decades || (explore[i] && spansDecades(b.lo[i], b.hi[i]));
  for (const bool in_log : {false, true}) {
    if (in_log && !any_decades) break;
    std::mt19937_64 rng(seed ^ (in_log ? 0x2545f4914f6cdd1dull : 0x9e3779b97f4a7c15ull));
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<std::vector<double>> strata(start.size());
    for (auto& v : strata) {
      for (int k = 0; k < n; ++k) v.push_back((k + U(rng)) / n);
      std::shuffle(v.begin(), v.end(), rng);
    }
    for (int k = 0; k < n; ++k) {
      std::vector<double> x = start;
      bool any = false;
      for (size_t i = 0; i < x.size() && i < explore.size(); ++i) {
        if (!explore[i]) continue;
        const double q = strata[i][static_cast<size_t>(k)];
        x[i] = in_log && spansDecades(b.lo[i], b.hi[i]) ? b.lo[i] * std::pow(b.hi[i] / b.lo[i], q)
                                                        : b.lo[i] + q * (b.hi[i] - b.lo[i]);
        any = true;
      }
      if (any) out.push_back(x);
    }
  }
  return out;
}

}  // namespace

void searchToModel(const std::vector<double>& x, std::vector<double>& p) {
  p = x;
  const double k = x[0] + x[1];
  p[0] = k;
  p[1] = std::fabs(k) > 1e-300 ? x[0] / k : 1.0;
}

std::vector<double> modelToSearch(const std::vector<double>& p) {
  std::vector<double> x = p;
  x[0] = p[0] * p[1];
  x[1] = p[0] * (1.0 - p[1]);
  return x;
}

double rmseFrom(const model::Model& m, const io::Measurement& d, size_t from) {
  const auto* load = d.column("load");
  std::vector<double> y(d.size());
  m.simulate(d.u.data(), load ? load->data() : nullptr, d.size(), d.Ts, y.data());
  double s = 0;
  size_t k = 0;
  for (size_t i = from; i < y.size(); ++i, ++k) s += (y[i] - d.y[i]) * (y[i] - d.y[i]);
  return k ? std::sqrt(s / static_cast<double>(k)) : 0.0;
}

double mse(const model::Model& m, const io::Measurement& d) {
  const auto* load = d.column("load");
  std::vector<double> y(d.size());
  m.simulate(d.u.data(), load ? load->data() : nullptr, d.size(), d.Ts, y.data());
  double s = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    const double e = y[i] - d.y[i];
    s += e * e;
  }
  return s / static_cast<double>(y.size());
}

// The Bouc-Wen core of a parameter vector (k, rho, b, alpha, beta, gamma, ...) is bounded for every
// input only when beta sign(alpha) + gamma > 0 (bouc_wen.cpp). An unbounded set can fit one record by
// coincidence and diverge on the next, so the search never takes one.
bool boundedCore(const std::vector<double>& p) {
  return model::boucWenBounded(model::BoucWenParams{p[0], p[1], p[2], p[3], p[4], p[5]});
}

namespace {
// The effects' parameters that are not explored held at the start's values: a box of zero width there
// (every search keeps a parameter with lo == hi where its first point has it). The core stays free.
void holdEffects(const std::vector<double>& start, const std::vector<bool>& explore, Bounds& b) {
  for (size_t i = model::kBoucWenParams; i < start.size(); ++i)
    if (!explore[i]) b.lo[i] = b.hi[i] = start[i];  // held, not searched: the record's box does not apply
}

// The box widened to hold a start where it does not; a fixed parameter (lo == hi) stays fixed. Returns
// each parameter widened, with the record's own box (the search's first two: the gains of u and h), but
// not one at the catalogue's default (a stop at "none", a lag of 0: the start did not choose it).
std::vector<std::string> widenToHold(const model::Model& structure, const std::vector<double>& start, Bounds& b) {
  const auto specs = structure.paramSpecs();
  model::Model catalogue;  // the structure at the catalogue's defaults
  for (int i = 0; i < structure.numEffects(); ++i) catalogue.addEffect(structure.effect(i).name());
  const auto defaults = modelToSearch(catalogue.params());
  std::vector<std::string> out;
  for (size_t i = 0; i < start.size(); ++i) {
    if (!(b.hi[i] > b.lo[i]) || (start[i] >= b.lo[i] && start[i] <= b.hi[i])) continue;
    const std::string name = i == 0 ? "k rho" : i == 1 ? "k (1 - rho)" : specs[i].name;
    if (start[i] != defaults[i])
      out.push_back(name + " " + io::fmt("%.6g", start[i]) + " lies outside this record's box (" +
                    io::fmt("%.6g", b.lo[i]) + " to " + io::fmt("%.6g", b.hi[i]) + ")");
    b.lo[i] = std::min(b.lo[i], start[i]);
    b.hi[i] = std::max(b.hi[i], start[i]);
  }
  return out;
}
}  // namespace

FitResult fit(const model::Model& structure, const io::Measurement& d, const FitSettings& s,
              const std::function<void(const char*, int, double)>& progress, const model::Model* start) {
  const auto t0 = std::chrono::steady_clock::now();
  if (structure.needsLoad() && !d.has("load"))
    throw std::invalid_argument(d.source + ": the model has the 'load' effect but the data has no 'load' column");
  Bounds b = dataBounds(structure, d);
  const int threads = s.ga.threads > 0 ? s.ga.threads : defaultThreads();
  const auto* load = d.column("load");
  // Per-thread model and output buffer: the cost runs allocation-free.
  std::vector<model::Model> models(static_cast<size_t>(threads), structure);
  std::vector<std::vector<double>> ybuf(static_cast<size_t>(threads), std::vector<double>(d.size()));
  const double* lp = load ? load->data() : nullptr;
  std::vector<std::vector<double>> pbuf(static_cast<size_t>(threads));
  // Stage by stage (model::StagedSimulation): a Jacobian column reruns only the stages its parameter
  // acts in, and a whole run's tight loop per stage is faster than simulate()'s sample by sample.
  std::vector<model::StagedSimulation> sims(static_cast<size_t>(threads));
  CostFn cost = [&](const std::vector<double>& x, int w) {
    auto& m = models[static_cast<size_t>(w)];
    auto& p = pbuf[static_cast<size_t>(w)];
    searchToModel(x, p);
    if (!boundedCore(p)) return std::numeric_limits<double>::max();
    m.setParams(p);
    auto& y = ybuf[static_cast<size_t>(w)];
    sims[static_cast<size_t>(w)].run(m, d.u.data(), lp, d.size(), d.Ts, y.data());
    double acc = 0;
    for (size_t i = 0; i < y.size(); ++i) {
      const double e = y[i] - d.y[i];
      acc += e * e;
    }
    return acc / static_cast<double>(y.size());
  };
  GaSettings gs = s.ga;
  gs.threads = threads;
  std::vector<std::string> widened;
  if (start) {
    // Seed: the start model's values where it has them, the structure's defaults elsewhere.
    model::Model seeded = structure;
    seeded.core() = start->core();
    for (int i = 0; i < start->numEffects(); ++i) {
      const auto& e = start->effect(i);
      if (!seeded.hasEffect(e.name())) continue;
      for (size_t q = 0; q < e.params().size(); ++q)
        seeded.setEffectParam(e.name(), e.params()[q].name, start->effectParams(i)[q]);
    }
    gs.start = modelToSearch(seeded.params());
    const auto specs = structure.paramSpecs();
    gs.explore.assign(specs.size(), false);
    for (size_t i = model::kBoucWenParams; i < specs.size(); ++i) {
      const std::string eff = specs[i].name.substr(0, specs[i].name.find('.'));
      gs.explore[i] = !start->hasEffect(eff);
    }
    if (s.box_holds_start) widened = widenToHold(structure, gs.start, b);
    if (s.hold_effects) holdEffects(gs.start, gs.explore, b);
  }
  FitResult out;
  out.widened = std::move(widened);
  OptResult r;
  const bool use_ga = s.method == FitMethod::Ga;
  if (use_ga) {
    r = geneticAlgorithm(cost, b.lo, b.hi, gs, [&](int g, double c) {
      if (progress) progress("ga", g, std::sqrt(c));
    });
    out.generations = r.iterations;
    out.evaluations = r.evaluations;
  } else {
    // Without a GA the first start is the start model (or the structure's defaults), in the box.
    r.x = gs.start.empty() ? modelToSearch(structure.params()) : gs.start;
    for (size_t i = 0; i < r.x.size(); ++i) r.x[i] = std::clamp(r.x[i], b.lo[i], b.hi[i]);
    r.cost = cost(r.x, 0);
    ++out.evaluations;
  }
  if (s.refine && s.lm_iterations > 0) {
    std::vector<std::vector<double>> pb(static_cast<size_t>(threads));
    ResidualFn resid = [&](const std::vector<double>& x, std::vector<double>& e, int w) {
      auto& m = models[static_cast<size_t>(w)];
      auto& p = pb[static_cast<size_t>(w)];
      searchToModel(x, p);
      if (!boundedCore(p)) {
        std::fill(e.begin(), e.end(), 1e6);  // a step into an unbounded set is refused by its cost
        return;
      }
      m.setParams(p);
      sims[static_cast<size_t>(w)].run(m, d.u.data(), lp, d.size(), d.Ts, e.data());
      for (size_t i = 0; i < e.size(); ++i) e[i] -= d.y[i];
    };
    // Short LM runs from the best and the GA's distinct runners-up, then the best of them to the end:
    // the GA finds basins, LM their bottoms.
    std::vector<std::vector<double>> starts = {r.x};
    for (size_t k = 0; k < r.runners_up.size() && static_cast<int>(k) < s.lm_starts; ++k)
      starts.push_back(r.runners_up[k]);
    std::vector<std::vector<double>> spread;  // starts spread over the box, not from the GA
    {
      std::mt19937_64 rng(gs.seed ^ 0x5851f42d4c957f2dull);
      std::uniform_real_distribution<double> U(0.0, 1.0);
      const int n = s.lm_spread_starts;
      std::vector<std::vector<double>> strata(r.x.size());
      for (auto& v : strata) {
        for (int k = 0; k < n; ++k) v.push_back((k + U(rng)) / n);
        std::shuffle(v.begin(), v.end(), rng);
      }
      for (int k = 0; k < n; ++k) {
        std::vector<double> x(r.x.size());
        for (size_t i = 0; i < x.size(); ++i) x[i] = b.lo[i] + strata[i][static_cast<size_t>(k)] * (b.hi[i] - b.lo[i]);
        // Fixed parameters (lo == hi) stay where the first start has them.
        for (size_t i = 0; i < x.size(); ++i)
          if (!(b.hi[i] > b.lo[i])) x[i] = r.x[i];
        spread.push_back(x);
      }
    }
    if (!gs.start.empty()) {
      const auto warm = warmStarts(gs.start, gs.explore, b, s.lm_warm_starts, gs.seed);
      starts.insert(starts.end(), warm.begin(), warm.end());
    }
    // Short runs from every start, then the best few of each group to the end. A start spread over the
    // box wins only by a clear margin: where the first group's basin already fits, another basin that
    // fits the record as well may be a degenerate one that does not generalise (a slew limit that never
    // binds). The runs of a group go on at once, one per worker; each run is deterministic, so the
    // result does not depend on the number of threads.
    const bool multi = starts.size() + spread.size() > 1;
    auto runAll = [&](const std::vector<std::vector<double>>& xs, int iterations) {
      std::vector<OptResult> runs(xs.size());
      std::atomic<size_t> next{0};
      auto work = [&](int w) {
        for (size_t k = next++; k < xs.size(); k = next++)
          runs[k] = levenbergMarquardt(resid, d.size(), xs[k], b.lo, b.hi, iterations, 1, w, s.lm_tolerance,
                                       s.lm_undamped_check);
      };
      const int nt = std::min<int>(threads, static_cast<int>(xs.size()));
      if (xs.size() == 1) {
        // A single run: its Jacobian's columns go to the workers instead.
        runs[0] = levenbergMarquardt(resid, d.size(), xs[0], b.lo, b.hi, iterations, threads, 0, s.lm_tolerance,
                                     s.lm_undamped_check);
      } else if (nt <= 1) {
        work(0);
      } else {
        std::vector<std::thread> ts;
        for (int w = 0; w < nt; ++w) ts.emplace_back(work, w);
        for (auto& t : ts) t.join();
      }
      for (const auto& l : runs) out.evaluations += l.evaluations;
      return runs;
    };
    auto group = [&](const std::vector<std::vector<double>>& xs, std::size_t keep) {
      std::vector<OptResult> runs = runAll(xs, multi ? 8 : s.lm_iterations);
      std::stable_sort(runs.begin(), runs.end(),
                       [](const OptResult& a, const OptResult& c) { return a.cost < c.cost; });
      // The best few to the end: after eight iterations the eventual winner is not always ahead (a
      // hysteretic effect's width and the core's beta/gamma trade places before they settle).
      runs.resize(std::min(keep, runs.size()));
      if (multi) {
        std::vector<std::vector<double>> xk;
        for (const auto& l : runs) xk.push_back(l.x);
        const std::vector<OptResult> fin = runAll(xk, s.lm_iterations);
        for (size_t k = 0; k < runs.size(); ++k)
          if (fin[k].cost < runs[k].cost) runs[k] = fin[k];
      }
      OptResult best;
      best.cost = std::numeric_limits<double>::max();
      for (const auto& l : runs)
        if (l.cost < best.cost) best = l;
      return best;
    };
    const auto keep = static_cast<std::size_t>(std::max(1, s.lm_keep));
    OptResult best_l = group(starts, keep);
    if (!spread.empty()) {
      const OptResult far = group(spread, keep);
      // Without a GA the spread starts are the search itself, not a second opinion.
      if (far.cost < (use_ga ? 0.9 : 1.0) * best_l.cost) best_l = far;
    }
    if (best_l.cost <= r.cost) r = best_l;
    if (progress) progress("refine", best_l.iterations, std::sqrt(r.cost));
  }
  // The Nelder-Mead polish is for effects whose cost has kinks (dead band, delay, friction); after
  // Levenberg-Marquardt from several starts the plain core's fit ends where it would (same RMSE on the
  // benchmark records), so the multi-start method skips it there.
  const bool polish = !(s.method == FitMethod::MultiStart && structure.numEffects() == 0);
  if (s.refine && s.refine_evals > 0 && polish) {
    OptResult n = nelderMead(cost, r.x, b.lo, b.hi, s.refine_evals);
    out.evaluations += n.evaluations;
    if (n.cost <= r.cost) r = n;
    if (progress) progress("refine", n.iterations, std::sqrt(r.cost));
  }
  out.model = structure;
  std::vector<double> p;
  searchToModel(r.x, p);
  out.model.setParams(p);
  out.model.setRange(model::OperatingRange::of(d.u.data(), d.y.data(), d.size(), d.Ts));
  out.mse = r.cost;
  out.rmse = std::sqrt(r.cost);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace pamc::ident
