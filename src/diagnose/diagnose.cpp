#include "diagnose/diagnose.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "io/model_file.hpp"
#include "model/probe.hpp"
#include "report/figures.hpp"

#include "io/text.hpp"

namespace pamc::diagnose {

namespace {

using io::fmt;

// Candidates, pruning and probes are fitted on the screening record: the training record decimated by
// the largest step that leaves at least this many samples (every k-th sample; a record of fewer than
// twice as many is screened whole), so the whole record - all its levels and rates - is seen at a
// fraction of the cost (the first samples alone missed the end stops of the 150 000-sample record in
// docs/PERFORMANCE.md); a fit taken into the ladder is then refitted on all of it.
constexpr size_t kScreenSamples = 12500;
// A screening fit ranks the candidates to a percent (min_gain is 10 %), not to the last digit: its
// Levenberg-Marquardt runs stop at this relative step; the fit taken into the ladder is refitted to
// convergence on all the training data.
constexpr double kScreenTolerance = 1e-5;
// How hard a candidate or probe is searched. Quick: Levenberg-Marquardt from the current model and
// kQuickStarts starts spread over the new structure's parameters, no Nelder-Mead polish - enough to
// rank. Full: the fit's own number of starts and the polish. Every candidate and probe is searched
// quickly; the best of them are searched in full (kFullSearches candidates - the ladder is built from
// them - and kFullProbes probes), and the better fit is kept.
enum class Search { Quick, Full };
constexpr int kQuickStarts = 2;
// ... but a new structure with few parameters gets kQuickCover / (their number) starts: the cost of a
// threshold, a knee or a delay is flat away from the right value, and LM finds that only from a start
// near it (one dead band's threshold: eight starts, one per eighth of its range). Not for the probes:
// they say what kind of structure is missing, to the few percent their ranking needs.
constexpr int kQuickCover = 8;
constexpr int kQuickIterations = 10;
constexpr size_t kFullSearches = 2;
constexpr size_t kFullProbes = 0;
// Two searches of one structure whose validated errors differ by less than this fraction found the
// same basin.
constexpr double kAgree = 2e-3;

// A validated error below this multiple of the sensor noise leaves nothing to explain: the ladder
// stops adding effects and the probes are not run.
constexpr double kAtNoise = 1.5;
// A validation error whose mean square is at least this much its mean's: an offset between the records.
constexpr double kOffsetShare = 0.8;

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// fn(0) ... fn(n - 1), each index once, on up to `threads` workers.
template <class Fn>
void onWorkers(size_t n, int threads, Fn&& fn) {
  std::atomic<size_t> next{0};
  auto worker = [&] {
    for (size_t i = next++; i < n; i = next++) fn(i);
  };
  std::vector<std::thread> ts;
  for (int w = 0; w < std::min<int>(threads, static_cast<int>(n)); ++w) ts.emplace_back(worker);
  for (auto& t : ts) t.join();
}

// Where the validation error is measured.
struct Validation {
  const io::Measurement* data;
  size_t from;
  double rmse(const model::Model& m) const { return ident::rmseFrom(m, *data, from); }
};

std::vector<double> simulate(const model::Model& m, const io::Measurement& d) {
  const auto* load = d.column("load");
  std::vector<double> y(d.size());
  m.simulate(d.u.data(), load ? load->data() : nullptr, d.size(), d.Ts, y.data());
  return y;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " + ") + x;
  return s.empty() ? "(reference model)" : s;
}

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

}  // namespace

DiagnoseResult diagnose(const io::Measurement& data, const io::Measurement* val, const DiagnoseSettings& s) {
  const auto t0 = std::chrono::steady_clock::now();
  auto log = [&](const std::string& m) {
    if (s.log) s.log(m);
  };
  DiagnoseResult res;
  io::Measurement train;
  Validation v{};
  if (val) {
    train = data;
    v = {val, 0};
    res.validation = val->source;
  } else {
    if (!(s.holdout > 0.05 && s.holdout < 0.95)) throw std::invalid_argument("holdout fraction must be in (0.05, 0.95)");
    const auto n_train = static_cast<size_t>(static_cast<double>(data.size()) * (1.0 - s.holdout));
    if (n_train < 50 || data.size() - n_train < 50)
      throw std::invalid_argument(data.source + ": too few samples to hold out a validation part; give --validate");
    train = data.slice(0, n_train);
    v = {&data, n_train};
    res.validation = "held out: the last " + fmt("%.0f", 100 * s.holdout) + " % of " + data.source;
  }
  res.samples = train.size();
  res.val_samples = v.data->size() - v.from;
  const int threads = s.threads > 0 ? s.threads : ident::defaultThreads();

  // Candidates: the list given, or the whole catalogue without the names given with a leading '-'.
  std::vector<std::string> pool, without;
  for (const auto& c : s.candidates) (c.size() > 1 && c[0] == '-' ? without.push_back(c.substr(1)) : pool.push_back(c));
  if (!pool.empty() && !without.empty())
    throw std::invalid_argument("candidates: give either the effects to try or the ones to leave out ('-name'), not both");
  for (const auto& c : pool.empty() ? without : pool) {
    (void)model::makeEffect(c);  // unknown names fail here, listing the known ones
    if (model::findProbe(c))
      throw std::invalid_argument("candidates: '" + c + "' is a probe, not a physical effect (diagnose tries the probes itself)");
  }
  if (pool.empty())
    for (const auto& e : model::catalogue())
      if (std::find(without.begin(), without.end(), e.name) == without.end()) pool.emplace_back(e.name);
  const bool have_load = train.has("load") && v.data->has("load");
  pool.erase(std::remove_if(pool.begin(), pool.end(),
                            [&](const std::string& c) { return model::makeEffect(c)->needsLoad() && !have_load; }),
             pool.end());

  const size_t step = std::max<size_t>(1, train.size() / kScreenSamples);
  const io::Measurement screen = step > 1 ? train.decimate(step) : train;
  if (step > 1)
    log("screening on every " + std::to_string(step) + "th training sample (" + std::to_string(screen.size()) +
        " samples at " + fmt("%.4g", 1.0 / screen.Ts) + " Hz)");
  // Refit on the whole training record, starting from a fit on the screening record: every parameter
  // has a value to start from, so one Levenberg-Marquardt run from there, whatever the method.
  auto refitOnAll = [&](const model::Model& m) {
    ident::FitSettings ps = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
    ps.ga.threads = threads;
    ps.ga.seed = s.seed;
    ps.lm_spread_starts = 0;
    ps.lm_warm_starts = 0;
    // The screening fit was polished by Nelder-Mead; on all samples Levenberg-Marquardt alone moves it.
    ps.refine_evals = 0;
    ps.lm_tolerance = 1e-7;
    const auto rt = std::chrono::steady_clock::now();
    auto f = ident::fit(m, train, ps, {}, &m);
    log("  refitted on all " + std::to_string(train.size()) + " training samples: train " + fmt("%.5g", f.rmse) + " (" +
        fmt("%.1f", seconds(rt)) + " s)");
    return f;
  };
  // A fit taken into the ladder: refitted on all the training samples, the refit kept unless it
  // validates worse.
  auto refitIfBetter = [&](CandidateResult& c) {
    const auto f = refitOnAll(c.model);
    const double rv = v.rmse(f.model);
    if (rv <= c.rmse_val) c.model = f.model, c.rmse_train = f.rmse, c.rmse_val = rv;
  };

  // Baseline: the reference model, searched on the screening record and refitted on all of it.
  log("fitting the reference model (Bouc-Wen) on " + std::to_string(train.size()) + " samples ...");
  ident::FitSettings base = ident::FitSettings::forMethod(s.method);
  base.ga.seed = s.seed;
  base.ga.threads = threads;
  base.ga.population = 40;
  base.ga.max_generations = 100;
  base.ga.stall_generations = 20;
  if (s.method == ident::FitMethod::Ga) base.refine_evals = 300;
  auto bt = std::chrono::steady_clock::now();
  auto b = ident::fit(model::Model{}, screen, base);
  if (step > 1) b = refitOnAll(b.model);
  Rung rung{{}, b.rmse, v.rmse(b.model), b.model, {}, {}};
  res.ladder.push_back(rung);
  log("  reference model: RMSE train " + fmt("%.5g", rung.rmse_train) + ", validation " + fmt("%.5g", rung.rmse_val) +
      " (" + fmt("%.1f", seconds(bt)) + " s)");
  res.baseline_residual = analyze(train, simulate(b.model, train));

  std::string stop_reason = "the catalogue is exhausted";
  // Sensor noise of the training and validation outputs: below kAtNoise times it nothing is left to explain.
  double noise = res.baseline_residual.noise_floor;
  {
    io::Measurement vv = v.data->slice(v.from, v.data->size());
    noise = std::max(noise, analyze(vv, std::vector<double>(vv.size(), 0.0)).noise_floor);
  }
  // Each name added to `base` and fitted on the screening data, starting from base's parameters; in
  // parallel, one fit per worker.
  // Fits each structure on the screening data with `method`, warm-started from base_model
  // (structures[i] is labelled names[i]); in parallel, one fit per worker.
  auto fitEach = [&](const std::vector<model::Model>& structures, const model::Model& base_model,
                     const std::vector<std::string>& names, int round, const ResidualReport& rr, const std::string& tag,
                     ident::FitMethod method, Search search = Search::Full, int quick_cover = kQuickCover) {
    std::vector<CandidateResult> results(names.size());
    // The structures with the most parameters (the slowest fits) first, so that the workers finish
    // together; each result keeps its place and its seed.
    std::vector<size_t> order(names.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t a, size_t b) { return structures[a].numParams() > structures[b].numParams(); });
    std::mutex log_mu;
    const int workers = std::min<int>(threads, static_cast<int>(names.size()));
    onWorkers(names.size(), threads, [&](size_t k) {
      const size_t i = order[k];
      const auto ct = std::chrono::steady_clock::now();
      const model::Model& structure = structures[i];
      ident::FitSettings fs = ident::FitSettings::forMethod(method);
      fs.ga.population = 32;
      fs.ga.max_generations = 30;
      fs.ga.stall_generations = 10;
      fs.ga.threads = std::max(1, threads / workers);  // a single fit gets every worker
      fs.ga.seed = s.seed * 1000003u + static_cast<std::uint64_t>(round * 97 + static_cast<int>(i));
      fs.lm_iterations = 20;
      fs.lm_tolerance = kScreenTolerance;
      // The core is fitted already: the starts keep it and spread the new effect's parameters
      // (lm_warm_starts); starts spread over the whole box would mostly refit the core.
      if (method == ident::FitMethod::MultiStart) fs.lm_spread_starts = 0;
      if (method == ident::FitMethod::Ga) fs.refine_evals = 200;
      if (search == Search::Quick) {
        const int n_new = std::max(1, structure.numParams() - base_model.numParams());
        fs.lm_warm_starts = std::max(kQuickStarts, quick_cover / n_new);
        fs.lm_iterations = kQuickIterations;
        fs.lm_keep = 1;
        fs.refine_evals = 0;
      }
      // The GA's second opinion on a round's best (method lm) searches the new effect's ranges
      // itself: no Levenberg-Marquardt starts spread over the whole box after it.
      if (method == ident::FitMethod::Ga && s.method == ident::FitMethod::MultiStart) fs.lm_spread_starts = 0;
      const auto f = ident::fit(structure, screen, fs, {}, &base_model);
      CandidateResult& c = results[i];
      c.effect = names[i];
      c.model = f.model;
      c.rmse_train = screen.size() == train.size() ? f.rmse : ident::rmseFrom(f.model, train);
      c.rmse_val = v.rmse(f.model);
      c.evidence = effectEvidence(names[i], rr);
      c.seconds = seconds(ct);
      std::lock_guard<std::mutex> lk(log_mu);
      const std::string label = tag + names[i];
      log("  " + label + std::string(label.size() < 20 ? 20 - label.size() : 0, ' ') + " train " +
          fmt("%-10.5g", c.rmse_train) + " validation " + fmt("%-10.5g", c.rmse_val) + " (" + fmt("%.1f", c.seconds) + " s)");
    });
    return results;
  };
  // Each name added to base_model.
  auto fitOnTop = [&](const model::Model& base_model, const std::vector<std::string>& names, int round,
                      const ResidualReport& rr, const std::string& tag, ident::FitMethod method,
                      Search search = Search::Full, int quick_cover = kQuickCover) {
    std::vector<model::Model> structures;
    for (const auto& n : names) {
      structures.push_back(base_model);
      structures.back().addEffect(n);
    }
    return fitEach(structures, base_model, names, round, rr, tag, method, search, quick_cover);
  };
  // Every name on top of base_model searched quickly, the `full` best (by validated RMSE) again
  // in full; the better fit of each kept, best first. With the GA every fit is a full search.
  auto searchOnTop = [&](const model::Model& base_model, const std::vector<std::string>& names, int round,
                         const ResidualReport& rr, const std::string& tag, ident::FitMethod method, size_t full_n,
                         int quick_cover) {
    const bool staged = method == ident::FitMethod::MultiStart && names.size() > full_n;
    auto results =
        fitOnTop(base_model, names, round, rr, tag, method, staged ? Search::Quick : Search::Full, quick_cover);
    const auto byVal = [](const CandidateResult& a, const CandidateResult& b) { return a.rmse_val < b.rmse_val; };
    std::stable_sort(results.begin(), results.end(), byVal);
    if (staged) {
      std::vector<std::string> top;
      for (size_t i = 0; i < full_n; ++i) top.push_back(results[i].effect);
      const auto full = fitOnTop(base_model, top, round, rr, "full: " + tag, method, Search::Full);
      for (size_t i = 0; i < full.size(); ++i) {
        const bool agree = std::fabs(full[i].rmse_val - results[i].rmse_val) <= kAgree * results[i].rmse_val;
        if (full[i].rmse_val < results[i].rmse_val) results[i] = full[i];
        results[i].confirmed = agree;
      }
      std::stable_sort(results.begin(), results.end(), byVal);
    }
    return results;
  };
  for (int round = 1; round <= s.max_effects; ++round) {
    const Rung cur = res.ladder.back();  // a copy: the ladder grows below
    // At the noise level nothing is left to explain; the first round still runs, so the candidates
    // and their evidence are reported.
    const bool at_noise = cur.rmse_val < kAtNoise * noise;
    if (at_noise && round > 1) {
      stop_reason = "the validated error is at the sensor noise level (" + fmt("%.3g", noise) + " rms)";
      break;
    }
    std::vector<std::string> todo;
    for (const auto& c : pool) {
      if (cur.model.hasEffect(c)) continue;
      // An alternative to an effect already taken (force_loop / mass_spring), or one more state
      // than the estimator can carry: not a candidate on top of this model.
      try {
        model::Model m = cur.model;
        m.addEffect(c);
      } catch (const std::invalid_argument&) {
        continue;
      }
      todo.push_back(c);
    }
    if (todo.empty()) break;
    const ResidualReport rr = round == 1 ? res.baseline_residual : analyze(train, simulate(cur.model, train));
    log("round " + std::to_string(round) + ": trying " + std::to_string(todo.size()) + " effects on top of " +
        join(cur.effects));
    std::vector<CandidateResult> results = searchOnTop(cur.model, todo, round, rr, "", s.method, kFullSearches, kQuickCover);
    // An effect that holds its alternative as a special case (force_loop is mass_spring with friction
    // in the force balance) goes before it only when what it adds lowers the validated RMSE by
    // min_gain too, as any effect must to be added; otherwise it ranks right behind the alternative.
    if (const char* alt = model::makeEffect(results.front().effect)->alternativeTo()) {
      for (size_t i = 1; i < results.size(); ++i) {
        if (results[i].effect != alt) continue;
        // Not better by min_gain: it goes behind its alternative, and the order of the rest stands.
        if (!(results.front().rmse_val <= (1.0 - s.min_gain) * results[i].rmse_val))
          std::rotate(results.begin(), results.begin() + 1, results.begin() + static_cast<long>(i) + 1);
        break;
      }
    }
    if (s.method == ident::FitMethod::MultiStart && !results.front().confirmed) {
      // Levenberg-Marquardt from a few starts can end in a wrong basin of the new effect (a mass-spring's
      // frequency) where the GA, searching its whole range, does not: the round's best is searched
      // again by the GA, and the better fit kept - unless its quick and full searches, from different
      // starts, already ended in the same place.
      model::Model st = cur.model;
      st.addEffect(results.front().effect);
      const auto g = fitEach({st}, cur.model, {results.front().effect}, round, rr, "GA: ", ident::FitMethod::Ga);
      if (g.front().rmse_val < results.front().rmse_val) results.front() = g.front();
    }
    res.rounds.push_back(results);
    const auto& best = results.front();
    const double gain = 1.0 - best.rmse_val / cur.rmse_val;
    if (at_noise) {
      stop_reason = "the validated error is already at the sensor noise level (" + fmt("%.3g", noise) + " rms)";
      break;
    }
    if (!(gain >= s.min_gain)) {
      stop_reason = gain > 0 ? "the best candidate, " + best.effect + ", lowers the validated RMSE by only " +
                                   fmt("%.1f", 100 * gain) + " % (at least " + fmt("%.0f", 100 * s.min_gain) + " % needed)"
                             : "no candidate lowers the validated RMSE";
      break;
    }
    CandidateResult taken = best;
    refitIfBetter(taken);
    Rung next_rung{cur.effects, taken.rmse_train, taken.rmse_val, taken.model, {}, {}};
    next_rung.effects.push_back(best.effect);
    res.ladder.push_back(next_rung);
    log("  -> added " + best.effect + ": validated RMSE " + fmt("%.5g", cur.rmse_val) + " -> " + fmt("%.5g", next_rung.rmse_val) +
        " (" + fmt("%.1f", 100 * gain) + " % lower)");
    if (round == s.max_effects) stop_reason = "the limit of " + std::to_string(s.max_effects) + " effects was reached";
  }
  // Pruning: an effect taken early can lose its use once later ones are in (a mass-spring standing in
  // for a pressure lag that was not yet there). Each effect is taken out in turn and the rest refitted,
  // and an effect that holds a simpler one as a special case (Effect::alternativeTo: force_loop is
  // mass_spring with friction) is replaced by it. The removal that costs least is kept while the
  // validated error rises by less than a quarter of min_gain (or stays at the noise); failing that, the
  // replacement that costs least on the same terms.
  while (!res.ladder.back().effects.empty()) {
    const Rung cur = res.ladder.back();
    std::vector<model::Model> structures;
    std::vector<std::string> labels, out, in;
    auto structure = [&](const std::string& drop, const char* put) {
      model::Model m(cur.model.core());
      for (const auto& e : cur.effects) {
        if (e != drop) m.addEffect(e);
        else if (put) m.addEffect(put);
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
    if (structures.empty()) break;
    log("pruning: is every effect of " + join(cur.effects) + " still needed?");
    // Every parameter has a value to start from: Levenberg-Marquardt from there, whatever the method.
    auto fits = fitEach(structures, cur.model, labels, s.max_effects + 2, res.baseline_residual, "",
                        ident::FitMethod::MultiStart);
    const auto acceptable = [&](double rv) { return rv <= cur.rmse_val * (1.0 + s.min_gain / 4.0) || rv < 1.2 * noise; };
    // A screening fit ranks; next to the bound it decides. A removal that misses it by little (within
    // min_gain, or at kAtNoise times the noise) is refitted on all the training samples before it is
    // judged: an effect fitted on the decimated record can miss there what the whole record's fit does
    // not (the asymmetry's state integrates the input's increments, which decimation merges).
    for (size_t i = 0; i < fits.size(); ++i)
      if (in[i].empty() && !acceptable(fits[i].rmse_val) &&
          (fits[i].rmse_val < kAtNoise * noise || fits[i].rmse_val <= cur.rmse_val * (1.0 + s.min_gain)))
        refitIfBetter(fits[i]);
    size_t best = fits.size();
    for (int pass = 0; pass < 2 && best == fits.size(); ++pass)  // removals first, then replacements
      for (size_t i = 0; i < fits.size(); ++i)
        if (in[i].empty() == (pass == 0) && acceptable(fits[i].rmse_val) &&
            (best == fits.size() || fits[i].rmse_val < fits[best].rmse_val))
          best = i;
    if (best == fits.size()) break;
    // The smaller structure was fitted from where the larger one left its parameters; above the noise
    // it is searched again by the GA (the better fit kept) and refitted on all the training samples,
    // as a rung that adds an effect.
    if (!(fits[best].rmse_val < kAtNoise * noise)) {
      const auto g = fitEach({structures[best]}, cur.model, {labels[best]}, s.max_effects + 3, res.baseline_residual,
                             "GA: ", ident::FitMethod::Ga);
      if (g.front().rmse_val < fits[best].rmse_val) fits[best] = g.front();
      refitIfBetter(fits[best]);
    }
    const double rv = fits[best].rmse_val;
    Rung pruned{{}, fits[best].rmse_train, rv, fits[best].model, {}, {}};
    for (const auto& e : cur.effects)
      if (e != out[best]) pruned.effects.push_back(e);
      else if (!in[best].empty()) pruned.effects.push_back(in[best]);
    pruned.removed = out[best];
    pruned.replaced_by = in[best];
    log("  -> " + (in[best].empty() ? "removed " + out[best] : "replaced " + out[best] + " by " + in[best]) +
        ": validated RMSE " + fmt("%.5g", cur.rmse_val) + " -> " + fmt("%.5g", rv));
    res.ladder.push_back(std::move(pruned));
  }
  const Rung& fin = res.ladder.back();
  res.final_residual = analyze(train, simulate(fin.model, train));
  {
    const auto yv = simulate(fin.model, *v.data);
    double sum = 0.0;
    for (size_t i = v.from; i < yv.size(); ++i) sum += v.data->y[i] - yv[i];
    res.val_offset = yv.size() > v.from ? sum / static_cast<double>(yv.size() - v.from) : 0.0;
  }
  // Probes: when the catalogue leaves the validated error above the noise, which kind of structure
  // explains what is left, and where.
  if (s.probes && !(fin.rmse_val < kAtNoise * noise)) {
    std::vector<std::string> names;
    for (const auto& p : model::probes()) names.emplace_back(p.name);
    log("probes: which kind of structure explains what is left of " + join(fin.effects) + " ...");
    // A probe says what kind of structure is missing, it is not a model: LM from starts spread over its
    // parameters (lm_warm_starts) around the final model, whatever the method.
    const auto fits = searchOnTop(fin.model, names, s.max_effects + 1, res.final_residual, "probe ",
                                  ident::FitMethod::MultiStart, kFullProbes, 0);
    for (const auto& c : fits) {
      ProbeResult p;
      p.probe = c.effect;
      p.rmse_train = c.rmse_train;
      p.rmse_val = c.rmse_val;
      p.explains = std::max(0.0, 1.0 - (c.rmse_val * c.rmse_val) / std::max(fin.rmse_val * fin.rmse_val, 1e-300));
      p.meaning = model::findProbe(c.effect)->meaning;
      p.model = c.model;
      res.probes.push_back(std::move(p));
    }
    // Where each probe acts: its residual's breakdown on all the training samples, one probe per worker.
    onWorkers(res.probes.size(), threads, [&](size_t i) {
      res.probes[i].regime = mostImprovedRegime(res.final_residual, analyze(train, simulate(res.probes[i].model, train)));
    });
    std::stable_sort(res.probes.begin(), res.probes.end(),
                     [](const ProbeResult& a, const ProbeResult& b) { return a.rmse_val < b.rmse_val; });
    res.probe_rung = 1.0 - res.probes.front().rmse_val / fin.rmse_val >= s.min_gain;
  }
  std::string v_text;
  if (res.ladder.size() == 1) {
    v_text = "No effect in the catalogue explains the residual: " + stop_reason + ".";
  } else {
    std::string removed, replaced;
    for (const auto& g : res.ladder)
      if (g.removed.empty()) continue;
      else if (g.replaced_by.empty()) removed += (removed.empty() ? "" : ", ") + g.removed;
      else replaced += (replaced.empty() ? "" : ", ") + g.removed + " by " + g.replaced_by;
    std::string notes;
    if (!removed.empty()) notes += removed + " taken out again: no longer needed";
    if (!replaced.empty()) notes += (notes.empty() ? "" : "; ") + replaced + " replaced: the simpler form is enough";
    v_text = "Added " + join(fin.effects) + (notes.empty() ? "" : " (" + notes + ")") +
             ": validated RMSE " + fmt("%.4g", res.ladder.front().rmse_val) + " -> " +
             fmt("%.4g", fin.rmse_val) + " (" + fmt("%.1f", res.ladder.front().rmse_val / std::max(fin.rmse_val, 1e-300)) +
             "x lower). Stopped: " + stop_reason + ".";
  }
  // A model at the noise on the training record and far from it on the validation record: the records
  // differ in what one record cannot show. Mostly a constant offset there: they start in different states.
  const bool val_off = noise > 0 && fin.rmse_train < 2.0 * noise && !(fin.rmse_val < kAtNoise * noise);
  if (val_off) {
    v_text += " The remaining training error (" + fmt("%.3g", fin.rmse_train) + ") is at the sensor noise level (" +
              fmt("%.3g", noise) + " rms), but the validated error is " + fmt("%.0f", fin.rmse_val / noise) +
              "x it: the model holds on the training record and not on the validation record.";
    const double share = res.val_offset * res.val_offset / std::max(fin.rmse_val * fin.rmse_val, 1e-300);
    if (share >= kOffsetShare)
      v_text += " There it is off by a nearly constant " + fmt("%.3g", res.val_offset) + " (" + fmt("%.0f", 100 * share) +
                " % of its mean square): the records start in different states - a warm-up or a drift already under "
                "way at one of them, or a sensor zero that moved between them - which a fit on one record cannot tell "
                "from the model's own offset and gain. Record from a known start (a cold muscle, a zeroed sensor)" +
                std::string(val ? ", or validate on a later part of the same record (without --validate)." : ".");
    else
      v_text += " Something differs between the records that the training record does not show: its levels or rates, "
                "or a slow change between the recordings.";
  } else if (noise > 0 && fin.rmse_train < 2.0 * noise)
    v_text += " The remaining training error (" + fmt("%.3g", fin.rmse_train) + ") is at the sensor noise level (" +
              fmt("%.3g", noise) + " rms): nothing systematic is left to explain.";
  else if (noise > 0)
    v_text += " The remaining training error (" + fmt("%.3g", fin.rmse_train) + ") is " +
              fmt("%.0f", fin.rmse_train / noise) + "x the sensor noise (" + fmt("%.3g", noise) +
              " rms): something systematic is left that the catalogue does not capture.";
  if (!res.probes.empty()) {
    const auto& p = res.probes.front();
    if (res.probe_rung)
      v_text += " The probe " + p.probe + " explains " + fmt("%.0f", 100 * p.explains) +
                " % of what is left (validated RMSE " + fmt("%.4g", fin.rmse_val) + " -> " + fmt("%.4g", p.rmse_val) +
                "), most of it at " + p.regime + ": " + p.meaning + ". It is a probe, not part of the model.";
    else if (!val_off)
      v_text += " No probe explains what is left either (the best, " + p.probe + ", " + fmt("%.0f", 100 * p.explains) +
                " %): it may be noise that is not white, or structure none of the probes has.";
  }
  res.verdict = v_text;
  res.seconds = seconds(t0);
  return res;
}

nlohmann::json toJson(const DiagnoseResult& r) {
  nlohmann::json j;
  j["samples"] = r.samples;
  j["validation_samples"] = r.val_samples;
  j["validation"] = r.validation;
  j["baseline"] = {{"rmse_train", r.ladder.front().rmse_train}, {"rmse_val", r.ladder.front().rmse_val}};
  j["validation_offset"] = r.val_offset;  // mean of measured - final model there
  nlohmann::json c = nlohmann::json::array();
  if (!r.rounds.empty())
    for (const auto& x : r.rounds.front())
      c.push_back({{"effect", x.effect}, {"rmse_val", x.rmse_val}, {"rmse_train", x.rmse_train},
                   {"evidence", x.evidence.text}, {"evidence_strength", x.evidence.strength}});
  j["candidates"] = c;
  nlohmann::json l = nlohmann::json::array();
  for (const auto& g : r.ladder)
  {
    l.push_back({{"effects", g.effects}, {"rmse_train", g.rmse_train}, {"rmse_val", g.rmse_val}, {"probe", false}});
    if (!g.removed.empty()) l.back()["removed"] = g.removed;
    if (!g.replaced_by.empty()) l.back()["replaced_by"] = g.replaced_by;
  }
  if (r.probe_rung) {
    auto e = r.ladder.back().effects;
    e.push_back(r.probes.front().probe);
    l.push_back({{"effects", e}, {"rmse_train", r.probes.front().rmse_train}, {"rmse_val", r.probes.front().rmse_val}, {"probe", true}});
  }
  j["ladder"] = l;
  nlohmann::json pj = nlohmann::json::array();
  for (const auto& p : r.probes) {
    nlohmann::json params = nlohmann::json::object();  // the probe's fitted parameters: a first guess at the physics
    for (int i = 0; i < p.model.numEffects(); ++i)
      if (p.probe == p.model.effect(i).name())
        for (size_t q = 0; q < p.model.effect(i).params().size(); ++q)
          params[p.model.effect(i).params()[q].name] = p.model.effectParams(i)[q];
    pj.push_back({{"probe", p.probe}, {"rmse_val", p.rmse_val}, {"rmse_train", p.rmse_train}, {"explains", p.explains},
                  {"regime", p.regime}, {"meaning", p.meaning}, {"params", params}});
  }
  j["probes"] = pj;
  j["model"] = io::modelToJson(r.ladder.back().model);
  j["verdict"] = r.verdict;
  j["seconds"] = r.seconds;
  return j;
}

void writeReport(const DiagnoseResult& r, const io::Measurement& data, const io::Measurement* val,
                 const DiagnoseSettings& /*s*/, const std::string& dir, std::vector<std::string>* warnings) {
  ::mkdir(dir.c_str(), 0755);
  struct stat sb {};
  if (::stat(dir.c_str(), &sb) != 0 || !S_ISDIR(sb.st_mode)) throw std::runtime_error(dir + ": cannot create the report directory");
  const std::string p = dir + "/";
  // Ladder.
  {
    std::vector<double> rung, tr, va;
    std::string labels;
    for (size_t i = 0; i < r.ladder.size(); ++i) {
      rung.push_back(static_cast<double>(i));
      tr.push_back(r.ladder[i].rmse_train);
      va.push_back(r.ladder[i].rmse_val);
    }
    io::writeCsvAtomic(p + "ladder.csv", {"rung", "rmse_train", "rmse_val"}, {&rung, &tr, &va});
  }
  // Measured vs baseline vs final on the validation data.
  const io::Measurement& vd = val ? *val : data;
  const auto yb = simulate(r.ladder.front().model, vd);
  const auto yf = simulate(r.ladder.back().model, vd);
  std::vector<double> eb(vd.size()), ef(vd.size());
  for (size_t i = 0; i < vd.size(); ++i) eb[i] = vd.y[i] - yb[i], ef[i] = vd.y[i] - yf[i];
  io::writeCsvAtomic(p + "validation.csv", {"t", "u", "y", "y_reference", "y_final", "e_reference", "e_final"},
                     {&vd.t, &vd.u, &vd.y, &yb, &yf, &eb, &ef});
  // Residual tests of the baseline and the final model (training data).
  for (const auto& [name, rep] : {std::pair<std::string, const ResidualReport*>{"reference", &r.baseline_residual},
                                  {"final", &r.final_residual}}) {
    std::vector<double> lag, acf, up, dn;
    for (size_t i = 0; i < rep->acf.size(); ++i) {
      lag.push_back(static_cast<double>(i) * rep->lag_step_s);
      acf.push_back(rep->acf[i]);
      up.push_back(rep->conf);
      dn.push_back(-rep->conf);
    }
    std::vector<double> clag, ccf;
    for (size_t i = 0; i < rep->ccf_du.size(); ++i) {
      clag.push_back((static_cast<double>(i) - rep->max_lag) * rep->lag_step_s);
      ccf.push_back(rep->ccf_du[i]);
    }
    std::vector<double> cup(clag.size(), rep->conf), cdn(clag.size(), -rep->conf);
    io::writeCsvAtomic(p + "acf_" + name + ".csv", {"lag_s", "acf", "upper", "lower"}, {&lag, &acf, &up, &dn});
    io::writeCsvAtomic(p + "ccf_" + name + ".csv", {"lag_s", "ccf", "upper", "lower"}, {&clag, &ccf, &cup, &cdn});
  }
  // A folder used before keeps no probe table or chart that this diagnosis did not make.
  if (r.probes.empty())
    for (const char* f : {"probes.csv", "probes.png"}) std::remove((p + f).c_str());
  if (!r.probes.empty()) {
    // Probes: how much of what the final model leaves each explains (percent of the validated MSE).
    std::string t = "probe,explains_pct,rmse_val,regime\n";
    for (const auto& q : r.probes) {
      std::string regime = q.regime;
      std::replace(regime.begin(), regime.end(), ',', ';');
      t += q.probe + "," + fmt("%.2f", 100 * q.explains) + "," + fmt("%.6g", q.rmse_val) + "," + regime + "\n";
    }
    io::writeFileAtomic(p + "probes.csv", t);
  }
  io::writeModelFile(p + "model.json", r.ladder.back().model, {{"ladder", toJson(r)["ladder"]}});
  io::writeFileAtomic(p + "diagnosis.json", toJson(r).dump(2) + "\n");
  if (!report::haveGnuplot()) {
    if (warnings) warnings->push_back("gnuplot not found (apt-get install gnuplot-nox); figures skipped");
    return;
  }
  std::string err;
  const std::string vcsv = p + "validation.csv";
  auto fig = [&](const std::string& png, const std::string& title, const std::vector<report::Panel>& panels) {
    if (!report::renderFigure(p + png, title, panels, err) && warnings) warnings->push_back(err);
  };
  fig("ladder.png", "Error ladder: " + r.verdict.substr(0, 90),
      {{"RMSE after each added effect (0 = reference model)", "rung", "RMSE",
        {{p + "ladder.csv", "rung", "rmse_train", "training", "linespoints lw 2 pt 7"},
         {p + "ladder.csv", "rung", "rmse_val", "validation", "linespoints lw 2 pt 5"}}}});
  if (!r.probes.empty() && !report::renderBars(p + "probes.png", "Probes: share of what " + join(r.ladder.back().effects) +
                                                   " leaves that each explains (validation)",
                                               p + "probes.csv", 1, 2, "explained [%]", err) && warnings)
    warnings->push_back(err);
  fig("validation.png", "Validation data: measured, reference model and final model (" + join(r.ladder.back().effects) + ")",
      {{"measured and models over time", "t [s]", "y", {{vcsv, "t", "y", "measured"}, {vcsv, "t", "y_reference", "reference model"}, {vcsv, "t", "y_final", "final model"}}},
       {"loops: y against u", "u", "y", {{vcsv, "u", "y", "measured"}, {vcsv, "u", "y_reference", "reference model"}, {vcsv, "u", "y_final", "final model"}}},
       {"residual over time", "t [s]", "y - model", {{vcsv, "t", "e_reference", "reference model"}, {vcsv, "t", "e_final", "final model"}}}});
  fig("residual_tests.png", "Residual tests (training data) with 95 % bounds",
      {{"auto-correlation of the residual", "lag [s]", "acf",
        {{p + "acf_reference.csv", "lag_s", "acf", "reference model"}, {p + "acf_final.csv", "lag_s", "acf", "final model"},
         {p + "acf_reference.csv", "lag_s", "upper", "95 % bound", "lines dt 2 lc 'black'"},
         {p + "acf_reference.csv", "lag_s", "lower", "", "lines dt 2 lc 'black'"}}},
       {"cross-correlation of the residual with the input increments", "lag [s]", "ccf",
        {{p + "ccf_reference.csv", "lag_s", "ccf", "reference model"}, {p + "ccf_final.csv", "lag_s", "ccf", "final model"},
         {p + "ccf_reference.csv", "lag_s", "upper", "95 % bound", "lines dt 2 lc 'black'"},
         {p + "ccf_reference.csv", "lag_s", "lower", "", "lines dt 2 lc 'black'"}}}});
}

}  // namespace pamc::diagnose
