// The searches a diagnosis is made of: many structures fitted on the screening record in parallel, the
// quick-then-full staging, and the refit of a fit taken into the ladder on the whole training record.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>

#include "diagnose/diagnosis.hpp"
#include "io/text.hpp"

namespace pamc::diagnose::detail {

namespace {
using io::fmt;

// A screening fit ranks the candidates to a percent (min_gain is 10 %), not to the last digit: its
// Levenberg-Marquardt runs stop at this relative step; the fit taken into the ladder is refitted to
// convergence on all the training data.
constexpr double kScreenTolerance = 1e-5;
constexpr int kQuickStarts = 2;
constexpr int kQuickIterations = 10;
// Samples of the screening record a structure is simulated on to weigh its fit's cost (fitCosts).
constexpr size_t kCostSamples = 2000;
// Two searches of one structure whose validated errors differ by less than this fraction found the
// same basin.
constexpr double kAgree = 2e-3;

bool byValidation(const CandidateResult& a, const CandidateResult& b) { return a.rmse_val < b.rmse_val; }
}  // namespace

// Refit on the whole training record, starting from a fit on the screening record: every parameter
// has a value to start from, so one Levenberg-Marquardt run from there, whatever the method.
ident::FitResult Diagnosis::refitOnAll(const model::Model& m) const { return refitOn(m, train_); }

// One Levenberg-Marquardt run from the start model, whatever the method: no other starts, no polish.
ident::FitSettings Diagnosis::singleRun(double tolerance) const {
  ident::FitSettings ps = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
  ps.ga.threads = threads_;
  ps.ga.seed = s_.seed;
  ps.lm_spread_starts = 0;
  ps.lm_warm_starts = 0;
  ps.refine_evals = 0;
  ps.lm_tolerance = tolerance;
  return ps;
}

ident::FitResult Diagnosis::refitOn(const model::Model& m, const io::Measurement& data) const {
  // The screening fit was polished by Nelder-Mead; on all samples Levenberg-Marquardt alone moves it.
  const ident::FitSettings ps = singleRun(1e-7);
  const auto rt = std::chrono::steady_clock::now();
  auto f = ident::fit(m, data, ps, {}, &m);
  log("  refitted on " + std::to_string(data.size()) + " training samples: train " + fmt("%.5g", f.rmse) + " (" +
      fmt("%.1f", seconds(rt)) + " s)");
  return f;
}

// The final model refitted once more, past Levenberg-Marquardt's grown damping (lm_undamped_check): the
// ladder's refits stop where their damped steps gain little, and a structure with friction and stops can go
// on from there (seed 3 of the physics plant's whole stroke: 0.074 -> 0.027 mm on the training record,
// docs/MODELING.md). Only the end: with the check in every refit of the ladder its path changed, and the
// whole stroke ended worse at seeds 1 and 2. Then once more from the parameters the output holds weakly at
// their defaults (Effect::weaklyHeld): the ladder's path leaves them wherever its basin did (the oracle's
// guide case: 10.75x -> 5.61x the noise, docs/MODELING.md "The gas's law from its defaults"). Each kept
// where it validates better and trains no worse (polishFrom); the rung keeps its structure.
void Diagnosis::polish() {
  Rung& fin = res_.ladder.back();
  if (noise_ > 0 && fin.rmse_val < kAtNoise * noise_) return;
  const std::string name = "polish: " + join(fin.effects) + " past the damping";
  polishFrom(model::Model(fin.model), name, fin.model, fin.rmse_train, fin.rmse_val);
  std::string which;
  if (const auto restarted = ident::withWeakDefaults(fin.model, train_, &which))
    polishFrom(*restarted, name + ", " + which + " from their defaults", fin.model, fin.rmse_train, fin.rmse_val);
}

// One Levenberg-Marquardt run on all the training samples from `start`, past the grown damping, taken into
// (m, rmse_train, rmse_val) where it validates better and trains no worse (a start away from m that the run
// cannot leave is no fit: at seed 3 of u0 such a one, trained at 0.089 mm against 0.035, validated 3 %
// better); logged as `what`.
void Diagnosis::polishFrom(const model::Model& start, const std::string& what, model::Model& m, double& rmse_train,
                           double& rmse_val) const {
  ident::FitSettings ps = singleRun(1e-7);
  ps.lm_undamped_check = true;
  const auto t = std::chrono::steady_clock::now();
  const auto f = ident::fit(start, train_, ps, {}, &start);
  const double rv = v_.rmse(f.model);
  const double was_train = ident::rmseFrom(m, train_);  // the rung's own may be the screening record's
  log(what + ": train " + fmt("%.5g", f.rmse) + " validation " + fmt("%.5g", rv) + " (was " + fmt("%.5g", rmse_val) +
      ", " + fmt("%.1f", seconds(t)) + " s)");
  if (rv < rmse_val && f.rmse <= was_train) m = f.model, rmse_train = f.rmse, rmse_val = rv;
}

// A fit taken into the ladder: refitted on all the training samples, the refit kept unless it
// validates worse.
void Diagnosis::refitIfBetter(CandidateResult& c) const {
  const auto f = refitOnAll(c.model);
  const double rv = v_.rmse(f.model);
  if (rv <= c.rmse_val) c.model = f.model, c.rmse_train = f.rmse, c.rmse_val = rv;
}

// What a fit of each structure costs, to order the work by: its parameters (a Jacobian's columns) times
// the time one simulation of it takes on the screening record's first kCostSamples samples - a friction
// that solves for its state every sample costs more than its two parameters say.
std::vector<double> Diagnosis::fitCosts(const std::vector<model::Model>& structures) const {
  const size_t n = std::min(kCostSamples, screen_.size());
  const auto* load = screen_.column("load");
  std::vector<double> y(n), cost(structures.size());
  for (size_t i = 0; i < structures.size(); ++i) {
    const auto t = std::chrono::steady_clock::now();
    structures[i].simulate(screen_.u.data(), load ? load->data() : nullptr, n, screen_.Ts, y.data());
    cost[i] = (structures[i].numParams() + 1) * seconds(t);
  }
  return cost;
}

// Fits each structure on the screening data with `method`, warm-started from base_model
// (structures[i] is labelled names[i]); in parallel, one fit per worker.
std::vector<CandidateResult> Diagnosis::fitEach(const std::vector<model::Model>& structures,
                                                const model::Model& base_model, const std::vector<std::string>& names,
                                                int round, const ResidualReport& rr, const std::string& tag,
                                                ident::FitMethod method, Search search, int quick_cover) const {
  std::vector<CandidateResult> results(names.size());
  // The slowest fits first, so that the workers finish together; each result keeps its place and its seed.
  const auto cost = fitCosts(structures);
  std::vector<size_t> order(names.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return cost[a] > cost[b]; });
  std::mutex log_mu;
  const int workers = std::min<int>(threads_, static_cast<int>(names.size()));
  onWorkers(names.size(), threads_, [&](size_t k) {
    const size_t i = order[k];
    const auto ct = std::chrono::steady_clock::now();
    const model::Model& structure = structures[i];
    ident::FitSettings fs = ident::FitSettings::forMethod(method);
    fs.ga.population = 32;
    fs.ga.max_generations = 30;
    fs.ga.stall_generations = 10;
    fs.ga.threads = std::max(1, threads_ / workers);  // a single fit gets every worker
    fs.ga.seed = s_.seed * 1000003u + static_cast<std::uint64_t>(round * 97 + static_cast<int>(i));
    fs.lm_iterations = 20;
    fs.lm_tolerance = kScreenTolerance;
    // The core is fitted already: the quick starts keep it and spread the new effect's parameters
    // (lm_warm_starts); starts spread over the whole box would mostly refit the core. A full search keeps
    // the method's few starts spread over the whole box as well: an effect with a loop of its own
    // (asymmetry) can mirror the core's, and the core fitted without it may sit in the wrong basin for the
    // pair (hidden asymmetry on the oracle and the model plant: 0.15 mm from the warm starts, the noise
    // from the spread ones).
    if (method == ident::FitMethod::MultiStart && search != Search::Full) fs.lm_spread_starts = 0;
    if (method == ident::FitMethod::Ga) fs.refine_evals = 200;
    if (search != Search::Full) {
      fs.hold_effects = search == Search::Own;
      const int n_new = std::max(1, structure.numParams() - base_model.numParams());
      fs.lm_warm_starts = std::max(kQuickStarts, quick_cover / n_new);
      fs.lm_iterations = kQuickIterations;
      fs.lm_keep = 1;
      fs.refine_evals = 0;
    }
    // The GA's second opinion on a round's best (method lm) searches the new effect's ranges
    // itself: no Levenberg-Marquardt starts spread over the whole box after it.
    if (method == ident::FitMethod::Ga && s_.method == ident::FitMethod::MultiStart) fs.lm_spread_starts = 0;
    const auto f = ident::fit(structure, screen_, fs, {}, &base_model);
    CandidateResult& c = results[i];
    c.effect = names[i];
    c.model = f.model;
    c.rmse_train = screen_.size() == train_.size() ? f.rmse : ident::rmseFrom(f.model, train_);
    c.rmse_val = v_.rmse(f.model);
    c.evidence = effectEvidence(names[i], rr);
    c.seconds = seconds(ct);
    std::lock_guard<std::mutex> lk(log_mu);
    const std::string label = tag + names[i];
    log("  " + label + std::string(label.size() < 20 ? 20 - label.size() : 0, ' ') + " train " +
        fmt("%-10.5g", c.rmse_train) + " validation " + fmt("%-10.5g", c.rmse_val) + " (" + fmt("%.1f", c.seconds) +
        " s)");
  });
  return results;
}

// Each name added to base_model.
std::vector<CandidateResult> Diagnosis::fitOnTop(const model::Model& base_model, const std::vector<std::string>& names,
                                                 int round, const ResidualReport& rr, const std::string& tag,
                                                 ident::FitMethod method, Search search, int quick_cover) const {
  std::vector<model::Model> structures;
  for (const auto& n : names) {
    structures.push_back(base_model);
    structures.back().addEffect(n);
  }
  return fitEach(structures, base_model, names, round, rr, tag, method, search, quick_cover);
}

// Every name on top of base_model searched quickly, the `full_n` best (by validated RMSE) again
// in full; the better fit of each kept, best first. With the GA every fit is a full search.
std::vector<CandidateResult> Diagnosis::searchOnTop(const model::Model& base_model,
                                                    const std::vector<std::string>& names, int round,
                                                    const ResidualReport& rr, const std::string& tag,
                                                    ident::FitMethod method, size_t full_n, int quick_cover) const {
  const bool staged = method == ident::FitMethod::MultiStart && names.size() > full_n;
  auto results =
      fitOnTop(base_model, names, round, rr, tag, method, staged ? Search::Quick : Search::Full, quick_cover);
  std::stable_sort(results.begin(), results.end(), byValidation);
  if (!staged) return results;
  std::vector<std::string> top;
  for (size_t i = 0; i < full_n; ++i) top.push_back(results[i].effect);
  const auto full = fitOnTop(base_model, top, round, rr, "full: " + tag, method, Search::Full);
  for (size_t i = 0; i < full.size(); ++i) {
    const bool agree = std::fabs(full[i].rmse_val - results[i].rmse_val) <= kAgree * results[i].rmse_val;
    if (full[i].rmse_val < results[i].rmse_val) results[i] = full[i];
    results[i].confirmed = agree;
  }
  std::stable_sort(results.begin(), results.end(), byValidation);
  return results;
}

}  // namespace pamc::diagnose::detail
