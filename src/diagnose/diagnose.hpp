// The modelling loop: fit the reference model, look at where it fails, try every physical effect
// of the catalogue on the training data, keep the one that lowers the *validated* error most, and
// repeat until no candidate helps by a meaningful margin.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "diagnose/residual.hpp"
#include "diagnose/spectrum.hpp"
#include "ident/identify.hpp"
#include "io/measurement.hpp"
#include "model/model.hpp"

namespace pamc::diagnose {

struct DiagnoseResult;

struct DiagnoseSettings {
  double holdout = 0.3;                 // fraction held out at the end when no validation file is given
  int max_effects = 4;                  // rungs above the baseline
  double min_gain = 0.10;               // a candidate must lower the validated RMSE by this fraction
  std::vector<std::string> candidates;  // empty: the whole catalogue
  std::uint64_t seed = 1;
  int threads = 0;  // 0: all cores
  // How every fit is searched: Levenberg-Marquardt from starts around the current model, each round's
  // best searched again by the GA (default), or the paper's GA first for every fit - several times
  // slower (docs/PERFORMANCE.md).
  ident::FitMethod method = ident::FitMethod::MultiStart;
  // When the catalogue leaves the validated error above the noise, fit the probes (model/probe.hpp)
  // on top of the final model and report which kind of structure explains what is left.
  bool probes = true;
  // The form every model is fitted in (model::OutputForm): the aligned output unless asked otherwise.
  model::OutputForm output_form = model::OutputForm::Aligned;
  std::function<void(const std::string&)> log;
  // Called with the result so far after each step that can add a rung (the reference model, each round,
  // the pruning, each refinement, the polish), `after` naming the step: a run cut short keeps
  // what it reached (`pamc diagnose --out-dir` writes it). Its models carry the range they were fitted on.
  std::function<void(const DiagnoseResult& so_far, const std::string& after)> checkpoint;
};

struct CandidateResult {
  std::string effect;
  double rmse_train = 0, rmse_val = 0;
  Evidence evidence;
  model::Model model;
  double seconds = 0;
  // Searched quickly and in full, from different starts, with validated errors within kAgree of each
  // other: the two searches found the same basin.
  bool confirmed = false;
  // A probe fitted in place of this effect of the final model (ProbeEntry::stands_for); empty: on top.
  std::string replaces;
};

struct Rung {
  std::vector<std::string> effects;
  double rmse_train = 0, rmse_val = 0;
  model::Model model;
  std::string removed;      // a pruning rung: the effect taken out of the previous rung
  std::string replaced_by;  // ... and, if not empty, the simpler alternative put in its place
  std::string direction;    // a direction rung: what differs between rising and falling, in words
  bool refined = false;     // a refinement rung: replaced_by is a richer form that holds `removed` as a special case
};

// A probe fitted on top of the final physical model.
struct ProbeResult {
  std::string probe;
  double rmse_train = 0, rmse_val = 0;
  double explains = 0;    // fraction of the validated residual's mean square the probe removes
  std::string regime;     // where in compare's breakdown (training data) it removes the most
  std::string meaning;    // the kind of physics it points to (model/probes/probes.inc)
  std::string replaces;   // the final model's effect it was fitted in place of (empty: on top of the model)
  std::string direction;  // fitted with separate parameters rising and falling: what differs, in words
  // Taken by the directions step (Diagnosis::probeDirections): the validated RMSE of the symmetric fit it
  // replaced; 0 otherwise.
  double symmetric_rmse_val = 0;
  model::Model model;
  // "dead_zone", or "dead_zone for dead_band" when fitted in place of an effect.
  std::string label() const {
    return (direction.empty() ? probe : probe + " (rising/falling)") + (replaces.empty() ? "" : " for " + replaces);
  }
  // The final model's effects with this probe: the replaced one left out.
  std::vector<std::string> effectsWith(const std::vector<std::string>& final_effects) const;
};

struct DiagnoseResult {
  size_t samples = 0;  // training samples
  size_t val_samples = 0;
  std::string validation;                            // "held out: last 30 % of DATA" or the file name
  std::vector<Rung> ladder;                          // [0] is the baseline (reference model)
  std::vector<std::vector<CandidateResult>> rounds;  // candidates per round, best first
  std::vector<ProbeResult> probes;                   // best first; empty when the catalogue reached the noise
  bool probe_rung = false;                           // the best probe lowers the validated RMSE by min_gain or more
  std::string probes_unresolved;  // why the probes were not fitted (the screening record cannot resolve the model)
  ResidualReport baseline_residual, final_residual;  // on the training data
  ResidualSpectrum spectrum;                         // of the final model's residual on the training data
  double val_offset = 0;                             // mean of measured - final model on the validation data
  OffsetCourse val_offset_course;                    // ... over its first tenth and its second half
  std::string verdict;
  double seconds = 0;
};

// Validation: `val` if given, else the last `holdout` of `data` (scored in continuity with the
// training part, so the model enters it in the right state).
DiagnoseResult diagnose(const io::Measurement& data, const io::Measurement* val, const DiagnoseSettings& s);

// The stable JSON of `pamc diagnose --json`.
nlohmann::json toJson(const DiagnoseResult& r);

// Writes figures and CSVs of a diagnosis into dir (created if missing).
void writeReport(const DiagnoseResult& r, const io::Measurement& data, const io::Measurement* val,
                 const DiagnoseSettings& s, const std::string& dir, std::vector<std::string>* warnings = nullptr);

}  // namespace pamc::diagnose
