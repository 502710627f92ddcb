// The probes step of a diagnosis: the final model's residual, its spectrum and validation offset, and when
// the catalogue leaves the validated error above the noise, which kind of structure explains what is left.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "diagnose/diagnosis.hpp"
#include "diagnose/search_rules.hpp"
#include "io/text.hpp"
#include "model/probe.hpp"

namespace pamc::diagnose::detail {

namespace {
using io::fmt;

// A probe explaining less than this share of what is left gets no regime.
constexpr double kRegimeShare = 0.05;
// Phases the periodic probe is started from at a line of the spectrum (Diagnosis::fitTheLine).
constexpr int kLinePhases = 4;

// The bin of compare's breakdown (of at least 5 % of the samples) where a change of model lowers the
// mean squared error most: where the structure acts, not merely where most samples are.
std::string mostImprovedRegime(const ResidualReport& before, const ResidualReport& after) {
  const Bin* best = nullptr;
  double gain = 0, rb = 0, ra = 0;
  for (const auto& b : before.bins)
    for (const auto& a : after.bins)
      if (a.group == b.group && a.label == b.label && 20 * b.n >= before.n) {
        const double g = b.rmse * b.rmse - a.rmse * a.rmse;
        if (g > gain) gain = g, best = &b, rb = b.rmse, ra = a.rmse;
      }
  if (!best) return "no regime in particular";
  return best->group + " " + best->label + " (RMSE " + fmt("%.3g", rb) + " -> " + fmt("%.3g", ra) + ")";
}

// The probe that takes the place of `effect`: in its direction-dependent version when the effect is in
// its own (diagnose's directions step found that the data want separate rising and falling parameters
// there) and the probe has one; the probe itself otherwise.
std::string inThePlaceOf(const model::ProbeEntry& probe, const std::string& effect) {
  const bool updown = !model::directionalBase(effect).empty();
  return updown && probe.make()->directional() ? probe.name + std::string(model::kDirectionalSuffix) : probe.name;
}

}  // namespace

// The final model's residual and validation offset; when the catalogue leaves the validated error above
// the noise, which kind of structure explains what is left, and where.
void Diagnosis::probes() {
  const Rung& fin = res_.ladder.back();
  {
    const auto ym = simulate(fin.model, train_);
    res_.final_residual = analyze(train_, ym);
    std::vector<double> e(ym.size());
    for (size_t i = 0; i < ym.size(); ++i) e[i] = train_.y[i] - ym[i];
    res_.spectrum = residualSpectrum(e, train_.u, train_.Ts, noise_);
  }
  {
    const auto yv = simulate(fin.model, *v_.data);
    std::vector<double> e;
    for (size_t i = v_.from; i < yv.size(); ++i) e.push_back(v_.data->y[i] - yv[i]);
    double sum = 0.0;
    for (double x : e) sum += x;
    res_.val_offset = e.empty() ? 0.0 : sum / static_cast<double>(e.size());
    res_.val_offset_course = offsetCourse(e.data(), e.size());
  }
  if (!s_.probes) return;
  if (fin.rmse_val < kAtNoise * noise_) return alternativesAtTheNoise(fin);
  if (!screenResolves(fin)) return;
  log("probes: which kind of structure explains what is left of " + join(fin.effects) + " ...");
  auto fits = searchProbes(fin, Placement::OnTopAndInPlace);
  fitTheLine(fin, fits);
  recordProbes(fin, fits);
  preferSimplestProbe();
  probeDirections(fin);
  res_.probe_rung = 1.0 - res_.probes.front().rmse_val / fin.rmse_val >= s_.min_gain;
}

// The probes are searched on the screening record. Where its decimation moves the final model's own output
// by more than what is left of the training record (the pressure's fast dynamics under a 4 ms hold of the
// input: pneumatic_balance on the physics plant's whole stroke, 0.056 mm against 0.042 left), a probe's fit
// there answers the decimation, not the record - every probe then "explains" nothing. So also where the final
// structure itself, fitted there as a probe is (its "null probe"), validates worse by more than the share a
// probe must win (min_gain): a probe would first have to win back what the screening costs (the same record
// with the final model trained to 0.064 mm: the null probe 0.13 against 0.096 mm validated, every probe
// 0.115-0.48). They are not fitted, and the verdict says why (Diagnosis::probeText). The null probe is asked
// only where the decimation moves the final model's output by more than that share of what is left: where
// it moves it less, what a probe wins there is not the screening's (a direction-dependent lag the catalogue
// leaves at 2.4 mm trained, moved 0.09 mm: its null probe lost 20 % to a poor model's fit elsewhere, and
// the probe named it, 14x).
bool Diagnosis::screenResolves(const Rung& fin) {
  if (step_ <= 1) return true;
  const auto full = simulate(fin.model, train_);
  const auto screened = simulate(fin.model, screen_);
  double sum = 0.0;
  for (size_t j = 0; j < screened.size(); ++j) {
    const double d = screened[j] - full[j * step_];
    sum += d * d;
  }
  const double moved = std::sqrt(sum / static_cast<double>(std::max<size_t>(screened.size(), 1)));
  const std::string head =
      "The probes were not fitted: on the screening record they are searched on (every " + ordinal(step_) + " sample) ";
  double null_val = 0.0;
  const auto null_probe = [&] { return null_val = nullProbe(fin); };
  switch (screenVerdict(moved, fin.rmse_train, fin.rmse_val, s_.min_gain, null_probe)) {
    case ScreenVerdict::None: return true;
    case ScreenVerdict::Moves:
      res_.probes_unresolved = head + "the final model's own output moves by " + fmt("%.3g", moved) +
                               " rms, more than what is left of the training record (" + fmt("%.3g", fin.rmse_train) +
                               "); a probe fitted there would answer the decimation.";
      break;
    case ScreenVerdict::NullProbe:
      res_.probes_unresolved = head + "the final model itself, fitted there as a probe is, validates at " +
                               fmt("%.3g", null_val) + " against its own " + fmt("%.3g", fin.rmse_val) +
                               "; a probe would first have to win back what the screening costs.";
      break;
  }
  log("probes: " + res_.probes_unresolved);
  return false;
}

// The final structure searched on the screening record as a probe is (quickly, from itself), validated.
double Diagnosis::nullProbe(const Rung& fin) const {
  const auto fits = fitEach({fin.model}, fin.model, {"(none)"}, s_.max_effects + 1, res_.final_residual,
                            "null probe: ", ident::FitMethod::MultiStart, Search::Quick, 0);
  return fits.front().rmse_val;
}

// At the noise an effect of the final model may still stand in for a probe's physics in a simpler form:
// a play in the linkage taken for a Dahl friction with a short travel ends at 1.2x the noise. Each probe
// that may stand for an effect of the final model is fitted in its place; those that lower the validated
// RMSE by min_gain are reported (the verdict says the records tell the two apart only that far). On the
// catalogue's own physics at the noise none can.
void Diagnosis::alternativesAtTheNoise(const Rung& fin) {
  auto fits = searchProbes(fin, Placement::InPlaceOnly);
  const double limit = (1.0 - s_.min_gain) * fin.rmse_val;
  fits.erase(
      std::remove_if(fits.begin(), fits.end(), [limit](const CandidateResult& c) { return !(c.rmse_val <= limit); }),
      fits.end());
  if (fits.empty()) return;
  recordProbes(fin, fits);
  res_.probe_rung = true;
}

// The fitted probes as the result's list, best first, each with what it explains and where it acts.
void Diagnosis::recordProbes(const Rung& fin, const std::vector<CandidateResult>& fits_in) {
  auto fits = fits_in;
  std::stable_sort(fits.begin(), fits.end(),
                   [](const CandidateResult& a, const CandidateResult& b) { return a.rmse_val < b.rmse_val; });
  for (const auto& c : fits) {
    ProbeResult p;
    p.probe = c.effect;
    p.replaces = c.replaces;
    p.rmse_train = c.rmse_train;
    p.rmse_val = c.rmse_val;
    p.explains = std::max(0.0, 1.0 - (c.rmse_val * c.rmse_val) / std::max(fin.rmse_val * fin.rmse_val, 1e-300));
    p.meaning = model::findProbe(c.effect)->meaning;
    p.model = c.model;
    if (c.model.hasEffect(c.effect + model::kDirectionalSuffix)) p.direction = directionWords(c.model, c.effect);
    res_.probes.push_back(std::move(p));
  }
  // Where each probe that explains something acts: its residual's breakdown on all the training samples,
  // one probe per worker ("-" for one that explains less than kRegimeShare: its regime would be noise).
  onWorkers(res_.probes.size(), threads_, [&](size_t i) {
    ProbeResult& p = res_.probes[i];
    p.regime = p.explains < kRegimeShare
                   ? "-"
                   : mostImprovedRegime(res_.final_residual, analyze(train_, simulate(p.model, train_)));
  });
}

// Every probe on top of the final model, and each probe that may stand for an effect of it
// (ProbeEntry::stands_for) in that effect's place as well: an effect added before the probes run can absorb
// the physics a probe stands for in a simpler form (a play taken for Dahl friction, orifice flow for a
// first-order lag), and a probe on top of it then explains little. In the place of an effect's
// direction-dependent version the probe goes in its own (inThePlaceOf).
Diagnosis::ProbeStructures Diagnosis::probeStructures(const Rung& fin, Placement where) const {
  ProbeStructures ps;
  for (const auto& p : model::probes()) {
    if (where == Placement::OnTopAndInPlace) {
      ps.models.push_back(fin.model);
      ps.models.back().addEffect(p.name);
      ps.labels.emplace_back(p.name);
      ps.replaces.emplace_back();
    }
    for (const auto& e : fin.effects)
      if (p.standsFor(e)) {
        try {
          ps.models.push_back(withReplacement(fin, e, inThePlaceOf(p, e)));
        } catch (const std::invalid_argument& err) {  // a structure a model refuses: not a candidate
          log(std::string("probe ") + p.name + " for " + e + ": not built (" + err.what() + ")");
          continue;
        }
        ps.labels.push_back(std::string(p.name) + " for " + e);
        ps.replaces.push_back(e);
      }
  }
  return ps;
}

// The probes, searched on the screening record. A probe says what kind of structure is missing, it is not a
// model. On a final model with effects the probes on top are first ranked with those effects held, the
// core and the probe free (one parallel batch, Levenberg-Marquardt from starts spread over the probe's
// parameters: the effects' Jacobian columns are most of a fit's cost, and the core absorbs what it can of
// a missing structure, so a probe must be free to take it back); the best few of that ranking
// (kProbesSearched) and every probe in an effect's place - the ranking cannot fill the hole an effect taken
// out leaves - are searched quickly with everything free, and the best of all once more in full: it is
// fitted on top of whatever basin the catalogue's model ended in, and only a full search can move the core
// out of it (a curved valve characteristic: the quick search explained 50 % of what was left, the full one
// 97 %). Each probe keeps its best fit.
std::vector<CandidateResult> Diagnosis::searchProbes(const Rung& fin, Placement where) const {
  const ProbeStructures ps = probeStructures(fin, where);
  if (ps.models.empty()) return {};
  if (where == Placement::InPlaceOnly)
    log("at the noise: does a probe fit better in the place of an effect of " + join(fin.effects) + "?");
  std::vector<CandidateResult> fits(ps.models.size());
  std::vector<size_t> on_top, quick;
  for (size_t i = 0; i < fits.size(); ++i) {
    fits[i].effect = ps.labels[i].substr(0, ps.labels[i].find(' '));
    fits[i].replaces = ps.replaces[i];
    fits[i].model = ps.models[i];
    fits[i].rmse_train = fits[i].rmse_val = std::numeric_limits<double>::infinity();
    (ps.replaces[i].empty() ? on_top : quick).push_back(i);
  }
  const bool rank_first = fin.model.numEffects() > 0 && on_top.size() > kProbesSearched;
  if (rank_first) {
    searchAgain(ps, fits, fin, on_top, Search::Own, "probe ");
    on_top = bestProbes(fits, on_top, kProbesSearched);
  }
  quick.insert(quick.end(), on_top.begin(), on_top.end());
  searchAgain(ps, fits, fin, quick, Search::Quick, rank_first ? "quick: probe " : "probe ");
  std::vector<size_t> all(fits.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  searchAgain(ps, fits, fin, bestProbes(fits, all, 1), Search::Full, "full: probe ");
  return fits;
}

// Of the probes `among`, the indices of the `n` that validate best.
std::vector<size_t> Diagnosis::bestProbes(const std::vector<CandidateResult>& fits, std::vector<size_t> among,
                                          size_t n) {
  std::stable_sort(among.begin(), among.end(), [&](size_t a, size_t b) { return fits[a].rmse_val < fits[b].rmse_val; });
  among.resize(std::min(n, among.size()));
  return among;
}

// The probes `which` searched (`search`, from the final model), each fit kept where it validates better.
void Diagnosis::searchAgain(const ProbeStructures& ps, std::vector<CandidateResult>& fits, const Rung& fin,
                            const std::vector<size_t>& which, Search search, const std::string& tag) const {
  if (which.empty()) return;
  std::vector<model::Model> models;
  std::vector<std::string> labels;
  for (const size_t i : which) {
    models.push_back(ps.models[i]);
    labels.push_back(ps.labels[i]);
  }
  const auto again = fitEach(models, fin.model, labels, s_.max_effects + 1, res_.final_residual, tag,
                             ident::FitMethod::MultiStart, search, 0);
  for (size_t k = 0; k < which.size(); ++k) {
    CandidateResult& c = fits[which[k]];
    if (!(again[k].rmse_val < c.rmse_val)) continue;
    c.model = again[k].model;
    c.rmse_train = again[k].rmse_train;
    c.rmse_val = again[k].rmse_val;
  }
}

// A line of the residual's spectrum that is not coherent with the input names a sinusoid from elsewhere:
// that structure fitted - the `periodic` probe started at the line's frequency and amplitude, from
// kLinePhases phases (its cost in frequency is a comb with a tooth per 1 / record length, which no start
// spread over 0.5-200 Hz finds). It takes the place of the probe's own fit when it is better.
void Diagnosis::fitTheLine(const Rung& fin, std::vector<CandidateResult>& fits) const {
  const auto& peaks = res_.spectrum.peaks;
  const auto line = std::find_if(peaks.begin(), peaks.end(), [](const SpectrumPeak& p) { return !p.coherent; });
  if (line == peaks.end()) return;
  std::vector<model::Model> starts;
  for (int k = 0; k < kLinePhases; ++k) {
    model::Model m = fin.model;
    m.addEffect("periodic");
    m.setEffectParam("periodic", "freq", line->hz);
    m.setEffectParam("periodic", "amplitude", line->amplitude);
    m.setEffectParam("periodic", "phase", -M_PI + 2 * M_PI * (k + 0.5) / kLinePhases);
    starts.push_back(std::move(m));
  }
  std::vector<CandidateResult> tries;
  for (const auto& m : starts)  // each from its own phase
    tries.push_back(fitEach({m}, m, {"periodic"}, s_.max_effects + 1, res_.final_residual,
                            "line at " + fmt("%.2f", line->hz) + " Hz: ", ident::FitMethod::MultiStart, Search::Quick,
                            0)
                        .front());
  auto best = std::min_element(tries.begin(), tries.end(), [](const CandidateResult& a, const CandidateResult& b) {
    return a.rmse_val < b.rmse_val;
  });
  // The best phase searched to the end (Levenberg-Marquardt to convergence from it).
  auto full =
      fitEach({best->model}, best->model, {"periodic"}, s_.max_effects + 1, res_.final_residual,
              "full: line at " + fmt("%.2f", line->hz) + " Hz: ", ident::FitMethod::MultiStart, Search::Full, 0);
  if (full.front().rmse_val < best->rmse_val) *best = std::move(full.front());
  for (auto& c : fits)
    if (c.effect == "periodic" && c.replaces.empty() && best->rmse_val < c.rmse_val) c = *best;
}

// The top probe once more with separate parameters for a rising and a falling input (when it has that
// version), started from its fit and fitted on the screening record: it takes the symmetric fit's place
// when it lowers the validated RMSE by min_gain, and what differs is said in words.
void Diagnosis::probeDirections(const Rung& fin) {
  ProbeResult& top = res_.probes.front();
  if (!top.direction.empty() || !model::makeEffect(top.probe)->directional()) return;
  const Rung with{top.effectsWith(fin.effects), top.rmse_train, top.rmse_val, top.model, {}, {}, {}, false};
  const auto f = refitOn(withDirections(with, top.probe), screen_);
  const double rv = v_.rmse(f.model);
  log("directions: probe " + top.probe + " with separate rising and falling parameters: validation " + fmt("%.5g", rv) +
      " (was " + fmt("%.5g", top.rmse_val) + ")");
  if (1.0 - rv / top.rmse_val < s_.min_gain) return;
  top.symmetric_rmse_val = top.rmse_val;
  top.model = f.model;
  top.rmse_val = rv;
  top.rmse_train = ident::rmseFrom(f.model, train_);
  top.explains = std::max(0.0, 1.0 - (rv * rv) / std::max(fin.rmse_val * fin.rmse_val, 1e-300));
  top.direction = directionWords(f.model, top.probe);
}

// Among the probes that explain about as much as the best (validated RMSE within kProbeTie of it), the
// one with the fewest parameters goes first: a dead zone fitted by a two-parameter probe says more than
// the same shape drawn by an eight-parameter curve.
void Diagnosis::preferSimplestProbe() {
  if (res_.probes.empty()) return;
  auto size = [](const ProbeResult& p) { return model::findProbe(p.probe)->make()->params().size(); };
  const double limit = kProbeTie * res_.probes.front().rmse_val;
  size_t best = 0;
  for (size_t i = 1; i < res_.probes.size() && res_.probes[i].rmse_val <= limit; ++i)
    if (size(res_.probes[i]) < size(res_.probes[best])) best = i;
  std::rotate(res_.probes.begin(), res_.probes.begin() + static_cast<long>(best),
              res_.probes.begin() + static_cast<long>(best) + 1);
}

}  // namespace pamc::diagnose::detail

namespace pamc::diagnose {
std::vector<std::string> ProbeResult::effectsWith(const std::vector<std::string>& final_effects) const {
  std::vector<std::string> e;
  for (const auto& x : final_effects)
    if (x != replaces) e.push_back(x);
  e.push_back(probe);
  return e;
}
}  // namespace pamc::diagnose
