// diagnose(): the steps of diagnosis.hpp in order - screen, baseline, candidates, prune, refine
// (diagnose_refine.cpp), probes (diagnose_probes.cpp), verdict.
#include "diagnose/diagnose.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "diagnose/diagnosis.hpp"
#include "io/text.hpp"
#include "model/probe.hpp"

namespace pamc::diagnose {

namespace detail {

namespace {
using io::fmt;

// Candidates, pruning and probes are fitted on the screening record: the training record decimated by
// the largest step that leaves at least this many samples (every k-th sample; a record of fewer than
// twice as many is screened whole), so the whole record - all its levels and rates - is seen at a
// fraction of the cost (the first samples alone missed the end stops of the 150 000-sample record in
// docs/PERFORMANCE.md); a fit taken into the ladder is then refitted on all of it.
constexpr size_t kScreenSamples = 12500;
// ... but never to a sample time above this [s]: decimation merges the input's changes between the
// samples it keeps, and 12 ms (83 Hz; a step of 12 at 1 kHz, what the 150 000-sample record of
// docs/PERFORMANCE.md gets) still resolves the catalogue's lags and delays of tens of milliseconds.
// Without the cap a 25-minute record was screened at 8 Hz, where a 0.1 s lag is invisible, and the same
// physics got another ladder than its 2.5-minute record; with it the screening record grows with the
// record, and so does the cost (linearly: docs/PERFORMANCE.md).
constexpr double kMaxScreenTs = 0.012;
// A runner-up whose validated RMSE is within this factor of the best is a near tie, decided one round
// ahead (Diagnosis::breakTie).
constexpr double kTieFactor = 2.0;
// A validation error whose mean square is at least this much its mean's: an offset between the records.
constexpr double kOffsetShare = 0.8;

// The list given, or the catalogue without the names given with a leading '-' and without the effects
// that refine others (tried in their place instead: richerPool); effects that need a load column only
// when both records have one.
std::vector<std::string> candidatePool(const std::vector<std::string>& given, bool have_load) {
  std::vector<std::string> pool, without;
  for (const auto& c : given) (c.size() > 1 && c[0] == '-' ? without.push_back(c.substr(1)) : pool.push_back(c));
  if (!pool.empty() && !without.empty())
    throw std::invalid_argument(
        "candidates: give either the effects to try or the ones to leave out ('-name'), not both");
  for (const auto& c : pool.empty() ? without : pool) {
    (void)model::makeEffect(c);  // unknown names fail here, listing the known ones
    if (model::findProbe(c))
      throw std::invalid_argument("candidates: '" + c +
                                  "' is a probe, not a physical effect (diagnose tries the probes itself)");
  }
  if (pool.empty())
    for (const auto& e : model::catalogue())
      if (std::find(without.begin(), without.end(), e.name) == without.end() && e.make()->refines().empty())
        pool.emplace_back(e.name);
  pool.erase(std::remove_if(pool.begin(), pool.end(),
                            [&](const std::string& c) { return model::makeEffect(c)->needsLoad() && !have_load; }),
             pool.end());
  return pool;
}
// The effects that refine others (Effect::refines), unless left out with '-name' or a list of effects to
// try is given (then they are tried only when it names them, as candidates).
std::vector<std::string> richerPool(const std::vector<std::string>& given) {
  std::vector<std::string> richer;
  for (const auto& c : given)
    if (!(c.size() > 1 && c[0] == '-')) return richer;
  for (const auto& e : model::catalogue())
    if (!e.make()->refines().empty() && std::find(given.begin(), given.end(), "-" + std::string(e.name)) == given.end())
      richer.emplace_back(e.name);
  return richer;
}
}  // namespace

std::vector<double> simulate(const model::Model& m, const io::Measurement& d) {
  const auto* load = d.column("load");
  std::vector<double> y(d.size());
  m.simulate(d.u.data(), load ? load->data() : nullptr, d.size(), d.Ts, y.data());
  return y;
}

std::string ordinal(size_t n) {
  const size_t tens = n % 100, ones = n % 10;
  const char* suffix = tens >= 11 && tens <= 13 ? "th" : ones == 1 ? "st" : ones == 2 ? "nd" : ones == 3 ? "rd" : "th";
  return std::to_string(n) + suffix;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " + ") + x;
  return s.empty() ? "(reference model)" : s;
}

Diagnosis::Diagnosis(const io::Measurement& data, const io::Measurement* val, const DiagnoseSettings& s)
    : data_(data), val_(val), s_(s), t0_(std::chrono::steady_clock::now()) {}

DiagnoseResult Diagnosis::run() {
  screen();
  baseline();
  checkpoint("the reference model");
  candidates();
  prune();
  checkpoint("the pruning");
  refinements();
  directions();
  polish();
  checkpoint("the polish");
  probes();
  verdict();
  recordRange();
  res_.seconds = seconds(t0_);
  return std::move(res_);
}

// The result so far to DiagnoseSettings::checkpoint. Its models carry the range of the record they were
// fitted on (ident::fit records it); recordRange sets the training record's at the end.
void Diagnosis::checkpoint(const std::string& after) {
  if (!s_.checkpoint) return;
  res_.seconds = seconds(t0_);
  s_.checkpoint(res_, after);
}

void Diagnosis::recordRange() {
  const auto r = model::OperatingRange::of(train_.u.data(), train_.y.data(), train_.size(), train_.Ts);
  for (auto& rung : res_.ladder) rung.model.setRange(r);
  for (auto& p : res_.probes) p.model.setRange(r);
}

// The training and validation records, the candidates and the screening record.
void Diagnosis::screen() {
  if (val_) {
    train_ = data_;
    v_ = {val_, 0};
    res_.validation = val_->source;
  } else {
    if (!(s_.holdout > 0.05 && s_.holdout < 0.95))
      throw std::invalid_argument("holdout fraction must be in (0.05, 0.95)");
    const auto n_train = static_cast<size_t>(static_cast<double>(data_.size()) * (1.0 - s_.holdout));
    if (n_train < 50 || data_.size() - n_train < 50)
      throw std::invalid_argument(data_.source + ": too few samples to hold out a validation part; give --validate");
    train_ = data_.slice(0, n_train);
    v_ = {&data_, n_train};
    res_.validation = "held out: the last " + fmt("%.0f", 100 * s_.holdout) + " % of " + data_.source;
  }
  const auto [ulo, uhi] = std::minmax_element(train_.u.begin(), train_.u.end());
  const auto [ylo, yhi] = std::minmax_element(train_.y.begin(), train_.y.end());
  v_.inputs = {*ulo, *uhi};
  v_.span = *yhi - *ylo;
  res_.samples = train_.size();
  res_.val_samples = v_.data->size() - v_.from;
  threads_ = s_.threads > 0 ? s_.threads : ident::defaultThreads();
  pool_ = candidatePool(s_.candidates, train_.has("load") && v_.data->has("load"));
  richer_ = richerPool(s_.candidates);
  const size_t max_step = std::max<size_t>(1, static_cast<size_t>(kMaxScreenTs / train_.Ts + 1e-9));
  step_ = std::clamp<size_t>(train_.size() / kScreenSamples, 1, max_step);
  screen_ = step_ > 1 ? train_.decimate(step_) : train_;
  if (step_ > 1)
    log("screening on every " + ordinal(step_) + " training sample (" + std::to_string(screen_.size()) +
        " samples at " + fmt("%.4g", 1.0 / screen_.Ts) + " Hz)");
  log("the training record's " + ident::describeRests(ident::recordRests(train_)));
  log("a model that does not come to rest under a held command (within " + fmt("%.4g", v_.inputs.lo) + " .. " +
      fmt("%.4g", v_.inputs.hi) + ", at " + fmt("%.4g", 1e3 * v_.data->Ts) +
      " ms) validates at inf: no muscle swings under a held valve");
}

// The reference model, searched on the screening record and refitted on all of it; the sensor noise of
// the training and validation outputs: below kAtNoise times it nothing is left to explain.
void Diagnosis::baseline() {
  log("fitting the reference model (Bouc-Wen) on " + std::to_string(train_.size()) + " samples ...");
  ident::FitSettings base = ident::FitSettings::forMethod(s_.method);
  base.ga.seed = s_.seed;
  base.ga.threads = threads_;
  base.ga.population = 40;
  base.ga.max_generations = 100;
  base.ga.stall_generations = 20;
  if (s_.method == ident::FitMethod::Ga) base.refine_evals = 300;
  const auto bt = std::chrono::steady_clock::now();
  model::Model plain;
  plain.setOutputForm(s_.output_form);
  auto b = ident::fit(plain, screen_, base);
  if (step_ > 1) b = refitOnAll(b.model);
  const Rung rung{{}, b.rmse, v_.rmse(b.model), b.model, {}, {}, {}, false};
  res_.ladder.push_back(rung);
  log("  reference model: RMSE train " + fmt("%.5g", rung.rmse_train) + ", validation " + fmt("%.5g", rung.rmse_val) +
      " (" + fmt("%.1f", seconds(bt)) + " s)");
  res_.baseline_residual = analyze(train_, simulate(b.model, train_));
  noise_ = res_.baseline_residual.noise_floor;
  const io::Measurement vv = v_.data->slice(v_.from, v_.data->size());
  noise_ = std::max(noise_, analyze(vv, std::vector<double>(vv.size(), 0.0)).noise_floor);
}

// The pool's effects that can go on top of m: not in it, no alternative to one in it (force_loop /
// mass_spring), and no more states than the estimator can carry.
std::vector<std::string> Diagnosis::candidatesOnTop(const model::Model& m) const {
  std::vector<std::string> todo;
  for (const auto& c : pool_) {
    if (m.hasEffect(c)) continue;
    try {
      model::Model with = m;
      with.addEffect(c);
    } catch (const std::invalid_argument&) {
      continue;
    }
    todo.push_back(c);
  }
  return todo;
}

// One round: every candidate on top of the current rung, best first.
std::vector<CandidateResult> Diagnosis::searchRound(const Rung& cur, const std::vector<std::string>& todo, int round) {
  const ResidualReport rr = round == 1 ? res_.baseline_residual : analyze(train_, simulate(cur.model, train_));
  log("round " + std::to_string(round) + ": trying " + std::to_string(todo.size()) + " effects on top of " +
      join(cur.effects));
  auto results = searchOnTop(cur.model, todo, round, rr, "", s_.method, kFullSearches, kQuickCover);
  // An effect that holds its alternative as a special case (force_loop is mass_spring with friction
  // in the force balance) goes before it only when what it adds lowers the validated RMSE by
  // min_gain too, as any effect must to be added; otherwise it ranks right behind the alternative.
  // The two are compared on fits over all the training samples: the screening record's decimation
  // merges the input's changes between the samples it keeps, which the friction of force_loop absorbs
  // and a ringing mass_spring cannot (a payload at 8 Hz on the oracle: mass_spring 0.149 mm on the
  // screening fit, 0.005 on all samples; force_loop 0.019 and 0.005).
  if (const char* alt = model::makeEffect(results.front().effect)->alternativeTo()) {
    for (size_t i = 1; i < results.size(); ++i) {
      if (results[i].effect != alt) continue;
      refitIfBetter(results.front());
      refitIfBetter(results[i]);
      if (!(results.front().rmse_val <= (1.0 - s_.min_gain) * results[i].rmse_val))
        std::rotate(results.begin(), results.begin() + 1, results.begin() + static_cast<long>(i) + 1);
      break;
    }
  }
  if (!results.front().confirmed) secondOpinion(results.front(), cur.model, round, rr);
  return results;
}

// Levenberg-Marquardt from a few starts can end in a wrong basin of the new effect (a mass-spring's
// frequency) where the GA, searching its whole range, does not: a round's best is searched again by the
// GA (method lm), and the better fit kept - unless its quick and full searches, from different starts,
// already ended in the same place (CandidateResult::confirmed).
void Diagnosis::secondOpinion(CandidateResult& best, const model::Model& base, int round,
                              const ResidualReport& rr) const {
  if (s_.method != ident::FitMethod::MultiStart) return;
  model::Model st = base;
  st.addEffect(best.effect);
  const auto g = fitEach({st}, base, {best.effect}, round, rr, "GA: ", ident::FitMethod::Ga);
  if (g.front().rmse_val < best.rmse_val) best = g.front();
}

// Rounds that add the effect that lowers the validated error most, while it lowers it by min_gain.
void Diagnosis::candidates() {
  std::vector<CandidateResult> ahead;  // a round already searched by breakTie() on the rung it chose
  for (int round = 1; round <= s_.max_effects; ++round) {
    const Rung cur = res_.ladder.back();  // a copy: the ladder grows below
    // At the noise level nothing is left to explain; the first round still runs, so the candidates
    // and their evidence are reported.
    const bool at_noise = cur.rmse_val < kAtNoise * noise_;
    if (at_noise && round > 1) {
      stop_reason_ = "the validated error is at the sensor noise level (" + fmt("%.3g", noise_) + " rms)";
      return;
    }
    const auto todo = candidatesOnTop(cur.model);
    if (todo.empty()) return;
    res_.rounds.push_back(ahead.empty() ? searchRound(cur, todo, round) : std::move(ahead));
    ahead.clear();
    auto& results = res_.rounds.back();
    const double gain = 1.0 - results.front().rmse_val / cur.rmse_val;
    if (at_noise) {
      stop_reason_ = "the validated error is already at the sensor noise level (" + fmt("%.3g", noise_) + " rms)";
      return;
    }
    if (!(gain >= s_.min_gain)) {
      stop_reason_ = gain > 0
                         ? "the best candidate, " + results.front().effect + ", lowers the validated RMSE by only " +
                               fmt("%.1f", 100 * gain) + " % (at least " + fmt("%.0f", 100 * s_.min_gain) + " % needed)"
                         : "no candidate lowers the validated RMSE";
      return;
    }
    CandidateResult taken = results.front();
    if (round < s_.max_effects && nearTie(results, cur))
      taken = breakTie(results, cur, round, ahead);
    else
      refitIfBetter(taken);
    Rung next_rung{cur.effects, taken.rmse_train, taken.rmse_val, taken.model, {}, {}, {}, false};
    next_rung.effects.push_back(taken.effect);
    res_.ladder.push_back(next_rung);
    checkpoint("round " + std::to_string(round));
    log("  -> added " + taken.effect + ": validated RMSE " + fmt("%.5g", cur.rmse_val) + " -> " +
        fmt("%.5g", next_rung.rmse_val) + " (" + fmt("%.1f", 100 * (1.0 - next_rung.rmse_val / cur.rmse_val)) +
        " % lower)");
    if (round == s_.max_effects)
      stop_reason_ = "the limit of " + std::to_string(s_.max_effects) + " effects was reached";
  }
}

// The runner-up within kTieFactor of the round's best, both worth adding and above the noise, and not the
// best's alternative (searchRound() has ordered those). Two effects that each explain part of the same
// residual can rank far apart alone (a 0.1 s pressure lag with creep: an overdamped mass_spring 0.36 mm,
// the lag 0.61, while the lag with creep reaches the noise and the mass_spring with creep 0.15).
bool Diagnosis::nearTie(const std::vector<CandidateResult>& results, const Rung& cur) const {
  if (results.size() < 2 || results.front().rmse_val < kAtNoise * noise_) return false;
  const auto& a = results[0];
  const auto& b = results[1];
  const char* alt_a = model::makeEffect(a.effect)->alternativeTo();
  const char* alt_b = model::makeEffect(b.effect)->alternativeTo();
  if ((alt_a && b.effect == alt_a) || (alt_b && a.effect == alt_b)) return false;
  return b.rmse_val <= kTieFactor * a.rmse_val && b.rmse_val <= (1.0 - s_.min_gain) * cur.rmse_val;
}

// A near tie is decided one round ahead: each of the two is taken (refitted on all samples) and the next
// round searched on top of it; the one whose branch ends lower is taken, and its next round is handed
// back in `ahead` rather than searched again. Greedy choice between two effects that each explain part
// of the same residual took the wrong one: a 40 ms pressure lag plus creep on the oracle, where a
// mass_spring ranked 3 % ahead of the lag alone and the lag no longer fitted on top of it (10x the
// noise; with the lookahead both are found, at the noise).
CandidateResult Diagnosis::breakTie(std::vector<CandidateResult>& results, const Rung& cur, int round,
                                    std::vector<CandidateResult>& ahead) {
  log("  near tie between " + results[0].effect + " and " + results[1].effect + ": one round ahead on each");
  CandidateResult pick[2] = {results[0], results[1]};
  std::vector<CandidateResult> next[2];
  double score[2];
  bool at_noise[2];  // the branch explains the training record to the noise
  for (int i = 0; i < 2; ++i) {
    refitIfBetter(pick[i]);
    Rung r{cur.effects, pick[i].rmse_train, pick[i].rmse_val, pick[i].model, {}, {}, {}, false};
    r.effects.push_back(pick[i].effect);
    const auto todo = candidatesOnTop(r.model);
    if (!todo.empty()) {
      next[i] = searchRound(r, todo, round + 1);
      refitIfBetter(next[i].front());  // judged on all the samples, as a rung is
    }
    const CandidateResult& end =
        next[i].empty() || pick[i].rmse_val <= next[i].front().rmse_val ? pick[i] : next[i].front();
    score[i] = end.rmse_val;
    at_noise[i] = end.rmse_train < kAtNoise * noise_;
  }
  // By the validated error; but a branch that explains the training record to the noise goes before one
  // that does not: its validated error above the noise is the records' difference (a slow creep's state
  // at the validation record's start), which the other branch's wrong structure can trade against its
  // fit (hidden pressure lag and creep on the model plant: pressure_lag + creep at the noise on the
  // training record and 0.048 mm validated, mass_spring + creep 0.024 and 0.033).
  const int w = at_noise[0] != at_noise[1] ? (at_noise[1] ? 1 : 0) : (score[1] < score[0] ? 1 : 0);
  log("  -> " + pick[0].effect + " leads to " + fmt("%.5g", score[0]) + ", " + pick[1].effect + " to " +
      fmt("%.5g", score[1]) + ": taking " + pick[w].effect);
  if (w == 1) std::swap(results[0], results[1]);
  ahead = std::move(next[w]);
  return pick[w];
}

// An effect taken early can lose its use once later ones are in (a mass-spring standing in for a
// pressure lag that was not yet there). Each effect is taken out in turn and the rest refitted, and an
// effect that holds a simpler one as a special case (Effect::alternativeTo: force_loop is mass_spring
// with friction) is replaced by it. The removal that costs least is kept while the validated error rises
// by less than a quarter of min_gain (or stays at the noise); failing that, the replacement that costs
// least on the same terms.
void Diagnosis::prune() {
  while (!res_.ladder.back().effects.empty()) {
    const Rung cur = res_.ladder.back();
    std::vector<model::Model> structures;
    std::vector<std::string> labels, out, in;
    auto structure = [&](const std::string& drop, const char* put) {
      model::Model m(cur.model.core());
      m.setOutputForm(cur.model.outputForm());
      for (const auto& e : cur.effects) {
        if (e != drop)
          m.addEffect(e);
        else if (put)
          m.addEffect(put);
      }
      structures.push_back(std::move(m));
      out.push_back(drop);
      in.emplace_back(put ? put : "");
      labels.push_back(put ? drop + " -> " + put : "without " + drop);
    };
    if (cur.effects.size() >= 2)
      for (const auto& e : cur.effects) structure(e, nullptr);
    for (const auto& e : cur.effects)
      if (const char* alt = model::makeEffect(e)->alternativeTo()) structure(e, alt);
    if (structures.empty()) return;
    log("pruning: is every effect of " + join(cur.effects) + " still needed?");
    // Every parameter has a value to start from: Levenberg-Marquardt from there, whatever the method.
    auto fits = fitEach(structures, cur.model, labels, s_.max_effects + 2, res_.baseline_residual, "",
                        ident::FitMethod::MultiStart);
    const auto acceptable = [&](double rv) {
      return rv <= cur.rmse_val * (1.0 + s_.min_gain / 4.0) || rv < 1.2 * noise_;
    };
    // A screening fit ranks; next to the bound it decides. A removal that misses it by little (within
    // min_gain, or at kAtNoise times the noise) is refitted on all the training samples before it is
    // judged: an effect fitted on the decimated record can miss there what the whole record's fit does
    // not (the asymmetry's state integrates the input's increments, which decimation merges).
    // A replacement by the simpler alternative is refitted on all samples whenever it misses: the
    // decimation favours the effect with friction over the ringing one (see searchRound()).
    for (size_t i = 0; i < fits.size(); ++i)
      if (!acceptable(fits[i].rmse_val) && (!in[i].empty() || fits[i].rmse_val < kAtNoise * noise_ ||
                                            fits[i].rmse_val <= cur.rmse_val * (1.0 + s_.min_gain)))
        refitIfBetter(fits[i]);
    size_t best = fits.size();
    for (int pass = 0; pass < 2 && best == fits.size(); ++pass)  // removals first, then replacements
      for (size_t i = 0; i < fits.size(); ++i)
        if (in[i].empty() == (pass == 0) && acceptable(fits[i].rmse_val) &&
            (best == fits.size() || fits[i].rmse_val < fits[best].rmse_val))
          best = i;
    if (best == fits.size()) return;
    // The smaller structure was fitted from where the larger one left its parameters; above the noise
    // it is searched again by the GA (the better fit kept) and refitted on all the training samples,
    // as a rung that adds an effect.
    if (!(fits[best].rmse_val < kAtNoise * noise_)) {
      const auto g = fitEach({structures[best]}, cur.model, {labels[best]}, s_.max_effects + 3, res_.baseline_residual,
                             "GA: ", ident::FitMethod::Ga);
      if (g.front().rmse_val < fits[best].rmse_val) fits[best] = g.front();
      refitIfBetter(fits[best]);
    }
    const double rv = fits[best].rmse_val;
    Rung pruned{{}, fits[best].rmse_train, rv, fits[best].model, {}, {}, {}, false};
    for (const auto& e : cur.effects)
      if (e != out[best])
        pruned.effects.push_back(e);
      else if (!in[best].empty())
        pruned.effects.push_back(in[best]);
    pruned.removed = out[best];
    pruned.replaced_by = in[best];
    log("  -> " + (in[best].empty() ? "removed " + out[best] : "replaced " + out[best] + " by " + in[best]) +
        ": validated RMSE " + fmt("%.5g", cur.rmse_val) + " -> " + fmt("%.5g", rv));
    res_.ladder.push_back(std::move(pruned));
  }
}

// What the ladder did, in words.
std::string Diagnosis::ladderText() const {
  const Rung& fin = res_.ladder.back();
  if (res_.ladder.size() == 1) return "No effect in the catalogue explains the residual: " + stop_reason_ + ".";
  std::string removed, replaced, directions, refined;
  for (const auto& g : res_.ladder)
    if (g.removed.empty())
      continue;
    else if (!g.direction.empty())
      directions += (directions.empty() ? "" : "; ") + g.direction;
    else if (g.refined)
      refined += (refined.empty() ? "" : ", ") + g.removed + " refined to " + g.replaced_by;
    else if (g.replaced_by.empty())
      removed += (removed.empty() ? "" : ", ") + g.removed;
    else
      replaced += (replaced.empty() ? "" : ", ") + g.removed + " by " + g.replaced_by;
  std::string notes;
  if (!removed.empty()) notes += removed + " taken out again: no longer needed";
  if (!replaced.empty()) notes += (notes.empty() ? "" : "; ") + replaced + " replaced: the simpler form is enough";
  if (!refined.empty())
    notes += (notes.empty() ? "" : "; ") + refined + ": a richer form that holds it as a special case";
  if (!directions.empty()) notes += (notes.empty() ? "" : "; ") + directions;
  return "Added " + join(fin.effects) + (notes.empty() ? "" : " (" + notes + ")") + ": validated RMSE " +
         fmt("%.4g", res_.ladder.front().rmse_val) + " -> " + fmt("%.4g", fin.rmse_val) + " (" +
         fmt("%.1f", res_.ladder.front().rmse_val / std::max(fin.rmse_val, 1e-300)) +
         "x lower). Stopped: " + stop_reason_ + ".";
}

// The remaining training error against the noise: at it on both records, on the training record only
// (val_off: the records differ in what one record cannot show), or above it.
std::string Diagnosis::offsetText(bool val_off) const {
  const Rung& fin = res_.ladder.back();
  const std::string train_err = " The remaining training error (" + fmt("%.3g", fin.rmse_train) + ") is ";
  const std::string at_noise = "at the sensor noise level (" + fmt("%.3g", noise_) + " rms)";
  if (val_off) {
    std::string t = train_err + at_noise + ", but the validated error is " + fmt("%.0f", fin.rmse_val / noise_) +
                    "x it: the model holds on the training record and not on the validation record.";
    const double share = res_.val_offset * res_.val_offset / std::max(fin.rmse_val * fin.rmse_val, 1e-300);
    const std::string of_square = " (" + fmt("%.0f", 100 * share) + " % of its mean square)";
    const OffsetCourse& c = res_.val_offset_course;
    if (share >= kOffsetShare && c.buildsUp())
      return t + " There it is off by " + fmt("%.3g", res_.val_offset) + " on average" + of_square +
             ", but not from its start: " + fmt("%.3g", c.head) + " over its first tenth, " + fmt("%.3g", c.tail) +
             " over its second half. The model comes to settle elsewhere than the muscle on that input - a level, "
             "an amplitude or a loop of the hysteresis that the training record did not hold (a minor loop within "
             "its range, say) - rather than the records starting in different states. Train on a record that holds "
             "the validation record's kind of moves as well (docs/MODELING.md, \"Designing a record\").";
    if (share >= kOffsetShare)
      return t + " There it is off by a nearly constant " + fmt("%.3g", res_.val_offset) + of_square +
             ": the records start in different states - a warm-up or a drift already under "
             "way at one of them, or a sensor zero that moved between them - which a fit on one record cannot tell "
             "from the model's own offset and gain. Record from a known start (a cold muscle, a zeroed sensor)" +
             std::string(val_ ? ", or validate on a later part of the same record (without --validate)." : ".");
    return t +
           " Something differs between the records that the training record does not show: its levels or rates, "
           "or a slow change between the recordings.";
  }
  if (noise_ > 0 && fin.rmse_train < 2.0 * noise_)
    return train_err + at_noise + ": nothing systematic is left to explain.";
  if (noise_ > 0)
    return train_err + fmt("%.0f", fin.rmse_train / noise_) + "x the sensor noise (" + fmt("%.3g", noise_) +
           " rms): something systematic is left that the catalogue does not capture.";
  return "";
}

void Diagnosis::verdict() {
  const Rung& fin = res_.ladder.back();
  // A model at the noise on the training record and far from it on the validation record: the records
  // differ in what one record cannot show. Mostly a constant offset there: they start in different states.
  const bool val_off = noise_ > 0 && fin.rmse_train < 2.0 * noise_ && !(fin.rmse_val < kAtNoise * noise_);
  res_.verdict = ladderText() + offsetText(val_off) + probeText(val_off) +
                 " The residual: " + describeSpectrum(res_.spectrum) + ".";
}

// The best probe in words: what it explains and where; at the noise, the effect it fits better than.
std::string Diagnosis::probeText(bool val_off) const {
  if (!res_.probes_unresolved.empty()) return " " + res_.probes_unresolved;
  if (res_.probes.empty()) return "";
  const Rung& fin = res_.ladder.back();
  const auto& p = res_.probes.front();
  const std::string change = "(validated RMSE " + fmt("%.4g", fin.rmse_val) + " -> " + fmt("%.4g", p.rmse_val) + ")";
  if (res_.probe_rung && fin.rmse_val < kAtNoise * noise_)
    return " Though at the noise, the probe " + p.probe + " fits better still in the place of " + p.replaces + " " +
           change + ": " + p.meaning +
           ". On these records the two differ by that much; it is a probe, not part of the model.";
  if (res_.probe_rung)
    return " The probe " + p.probe + (p.replaces.empty() ? "" : " (in place of " + p.replaces + ")") + " explains " +
           fmt("%.0f", 100 * p.explains) + " % of what is left " + change + ", most of it at " + p.regime + ": " +
           p.meaning +
           (p.direction.empty() ? "" : "; fitted with separate parameters rising and falling, " + p.direction) +
           ". It is a probe, not part of the model.";
  if (!val_off)
    return " No probe explains what is left either (the best, " + p.label() + ", " + fmt("%.0f", 100 * p.explains) +
           " %): structure none of the probes has.";
  return "";
}

}  // namespace detail

DiagnoseResult diagnose(const io::Measurement& data, const io::Measurement* val, const DiagnoseSettings& s) {
  return detail::Diagnosis(data, val, s).run();
}

}  // namespace pamc::diagnose
