// The steps of one diagnosis (diagnose() runs them in order), for the files of src/diagnose only:
//   screen     the training and validation records, the candidates, the screening record
//   baseline   the reference model and the sensor noise the ladder stops at
//   candidates the rounds that add the effect that lowers the validated error most
//   prune      effects that lost their use taken out again, or replaced by a simpler alternative
//   refine     the final model's effects in richer forms and direction-dependent versions
//   probes     when the catalogue stops above the noise: which kind of structure explains the rest
//   verdict    what it all means, in words
// The searches they share (fits of many structures on the screening record, in parallel; refits on the
// whole training record) are in diagnose_search.cpp.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "diagnose/diagnose.hpp"
#include "diagnose/search_rules.hpp"
#include "model/held_rest.hpp"

namespace pamc::diagnose::detail {

// How hard a candidate or probe is searched. Quick: Levenberg-Marquardt from the current model and
// kQuickStarts starts spread over the new structure's parameters, no Nelder-Mead polish - enough to
// rank. Full: the fit's own number of starts and the polish. Every candidate and probe is searched
// quickly; the best of them are searched in full (kFullSearches candidates - the ladder is built from
// them - and the best probe), and the better fit is kept. Own: as Quick, with the effects the model has
// held where they are and only the core and the new structure's parameters fitted - the probes are
// ranked so first, and only the best few searched quickly (Diagnosis::searchProbes).
enum class Search { Own, Quick, Full };
// ... but a new structure with few parameters gets kQuickCover / (their number) starts: the cost of a
// threshold, a knee or a delay is flat away from the right value, and LM finds that only from a start
// near it (one dead band's threshold: eight starts, one per eighth of its range). Not for the probes:
// they say what kind of structure is missing, to the few percent their ranking needs.
constexpr int kQuickCover = 8;
constexpr size_t kFullSearches = 2;
// A validated error below this multiple of the sensor noise leaves nothing to explain: the ladder
// stops adding effects and the probes are not run.
constexpr double kAtNoise = 1.5;
// Probes whose validated RMSE is within this factor of the best's explain about as much: the one with
// the fewest parameters names the kind (Diagnosis::preferSimplestProbe).
constexpr double kProbeTie = 1.25;
// The probes on top searched quickly after their ranking with the final model's effects held: this many best.
constexpr size_t kProbesSearched = 4;

inline double seconds(std::chrono::steady_clock::time_point t0) {
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
// A model that does not come to rest under a held command over the training record's inputs, at the
// records' period (model::heldRest, judged against the training record's output span), validates at infinity:
// no muscle swings under a held valve, and a controller that inverts such a model swings the valve
// (docs/MODELING.md, "A model that does not come to rest").
struct Validation {
  const io::Measurement* data = nullptr;
  size_t from = 0;
  model::Interval inputs;  // the training record's
  double span = 0.0;       // the training record's output span
  double rmse(const model::Model& m) const {
    if (!model::heldRest(m, data->Ts, inputs.lo, inputs.hi, span).rests) return INFINITY;
    return ident::rmseFrom(m, *data, from);
  }
};

std::vector<double> simulate(const model::Model& m, const io::Measurement& d);
// "a + b + c", or "(reference model)" for none.
std::string join(const std::vector<std::string>& v);
// "every 3rd sample": n with its English ordinal suffix.
std::string ordinal(size_t n);
// The rung's model with `effect` replaced by `by` (empty: taken out), the parameters they share by name at
// its fit (diagnose_refine.cpp).
model::Model withReplacement(const Rung& fin, const std::string& effect, const std::string& by);
// The rung's model with `effect` in its direction-dependent version, both parameter sets at its fit; what
// differs between them, in words (diagnose_refine.cpp).
model::Model withDirections(const Rung& fin, const std::string& effect);
std::string directionWords(const model::Model& m, const std::string& effect);

class Diagnosis {
 public:
  Diagnosis(const io::Measurement& data, const io::Measurement* val, const DiagnoseSettings& s);
  DiagnoseResult run();

 private:
  // The steps, in order.
  void screen();
  void baseline();
  void candidates();
  void prune();
  // diagnose_refine.cpp: the final model in richer forms and direction-dependent versions.
  void refinements();
  void refineOne(const std::string& effect);
  std::optional<Rung> tryRefinement(const std::string& effect, const std::string& richer);
  bool lookAhead(Rung r);
  // Whether `now` is lower than `was` by min_gain.
  bool gains(double now, double was) const { return gainsBy(now, was, s_.min_gain); }
  void searchByGa(CandidateResult& c, const model::Model& base) const;
  bool searchAlong(CandidateResult& c, const std::string& richer) const;
  AlongPath walkAlong(const CandidateResult& c, const std::string& richer, double step, int steps,
                      std::optional<CandidateResult>& best) const;
  bool seedAtRest(model::Model& refined, const model::Model& rung, const std::string& richer) const;
  void searchFromRest(CandidateResult& c, const model::Model& refined, const Rung& cur, const std::string& richer,
                      const ResidualReport& rr) const;
  CandidateResult alongStep(const model::Model& start, const std::string& effect) const;
  void directions();
  void polish();
  void polishFrom(const model::Model& start, const std::string& what, model::Model& m, double& rmse_train,
                  double& rmse_val) const;
  void restartWeak(CandidateResult& c) const;
  void probes();
  // diagnose_probes.cpp: the probes on top of the final model and in the place of its effects.
  enum class Placement { OnTopAndInPlace, InPlaceOnly };
  std::vector<CandidateResult> searchProbes(const Rung& fin, Placement where) const;
  // The probes' structures on the final model, each with its label and the effect it replaces ("" on top).
  struct ProbeStructures {
    std::vector<model::Model> models;
    std::vector<std::string> labels, replaces;
  };
  ProbeStructures probeStructures(const Rung& fin, Placement where) const;
  static std::vector<size_t> bestProbes(const std::vector<CandidateResult>& fits, std::vector<size_t> among, size_t n);
  void searchAgain(const ProbeStructures& ps, std::vector<CandidateResult>& fits, const Rung& fin,
                   const std::vector<size_t>& which, Search search, const std::string& tag) const;
  void alternativesAtTheNoise(const Rung& fin);
  bool screenResolves(const Rung& fin);
  double nullProbe(const Rung& fin) const;
  void recordProbes(const Rung& fin, const std::vector<CandidateResult>& fits);
  void fitTheLine(const Rung& fin, std::vector<CandidateResult>& fits) const;
  void probeDirections(const Rung& fin);
  void preferSimplestProbe();
  void verdict();
  // Every model of the result holds where it was learnt: the training record's range.
  void recordRange();
  void checkpoint(const std::string& after);

  // candidates(): the effects that can go on top of the current model; one round's search.
  std::vector<std::string> candidatesOnTop(const model::Model& m) const;
  std::vector<CandidateResult> searchRound(const Rung& cur, const std::vector<std::string>& todo, int round);
  void secondOpinion(CandidateResult& best, const model::Model& base, int round, const ResidualReport& rr) const;
  bool nearTie(const std::vector<CandidateResult>& results, const Rung& cur) const;
  CandidateResult breakTie(std::vector<CandidateResult>& results, const Rung& cur, int round,
                           std::vector<CandidateResult>& ahead);
  // verdict(): the ladder in words; the records' disagreement when the model holds on one only.
  std::string ladderText() const;
  std::string offsetText(bool val_off) const;
  std::string probeText(bool val_off) const;

  // diagnose_search.cpp: fits on the screening record, refits on the whole training record.
  ident::FitResult refitOnAll(const model::Model& m) const;
  std::vector<double> fitCosts(const std::vector<model::Model>& structures) const;
  ident::FitResult refitOn(const model::Model& m, const io::Measurement& data) const;
  ident::FitSettings singleRun(double tolerance) const;
  void refitIfBetter(CandidateResult& c) const;
  std::vector<CandidateResult> fitEach(const std::vector<model::Model>& structures, const model::Model& base_model,
                                       const std::vector<std::string>& names, int round, const ResidualReport& rr,
                                       const std::string& tag, ident::FitMethod method, Search search = Search::Full,
                                       int quick_cover = kQuickCover) const;
  std::vector<CandidateResult> fitOnTop(const model::Model& base_model, const std::vector<std::string>& names,
                                        int round, const ResidualReport& rr, const std::string& tag,
                                        ident::FitMethod method, Search search = Search::Full,
                                        int quick_cover = kQuickCover) const;
  std::vector<CandidateResult> searchOnTop(const model::Model& base_model, const std::vector<std::string>& names,
                                           int round, const ResidualReport& rr, const std::string& tag,
                                           ident::FitMethod method, size_t full_n, int quick_cover) const;
  void log(const std::string& m) const {
    if (s_.log) s_.log(m);
  }

  const io::Measurement& data_;
  const io::Measurement* val_;
  const DiagnoseSettings& s_;
  std::chrono::steady_clock::time_point t0_;
  int threads_ = 1;
  io::Measurement train_;            // the training record
  Validation v_;                     // where the validated error is measured
  io::Measurement screen_;           // the training record decimated for the searches
  size_t step_ = 1;                  // its decimation
  std::vector<std::string> pool_;    // candidate effects
  std::vector<std::string> richer_;  // effects tried only in the place of those they refine
  double noise_ = 0;                 // sensor noise of the records (rms)
  std::string stop_reason_ = "the catalogue is exhausted";
  DiagnoseResult res_;
};

}  // namespace pamc::diagnose::detail
