// Identification of a model (Bouc-Wen core and any effects) from a measurement:
// fitness = MSE of eq. (20) between the measured and the simulated output, minimised over box bounds
// scaled to the data - by the paper's GA followed by Levenberg-Marquardt (FitMethod::Ga), or by
// Levenberg-Marquardt from starts spread over the box alone (FitMethod::MultiStart) - then polished
// by Nelder-Mead.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ident/optimize.hpp"
#include "io/measurement.hpp"
#include "model/model.hpp"

namespace pamc::ident {

// Whether a record rests on an end stop at the lowest and at the highest of its output, as the search's
// box for a stop reads it (dataBounds boxes a stop within the record only there; identify.cpp says how it
// is judged and why). `pamc compare` prints it.
struct ExtremeRest {
  double share = 0.0;        // of the record's samples near the extreme
  double input_moved = 0.0;  // the input's travel over those samples, over the input's range
  bool on_stop = false;
};
struct RecordRests {
  ExtremeRest low, high;
};
RecordRests recordRests(const io::Measurement& d);
// One line: the rule and both extremes' figures.
std::string describeRests(const RecordRests& r);

enum class FitMethod {
  Ga,          // the paper's genetic algorithm, then LM from its best points and spread starts
  MultiStart,  // LM from the start model (or the defaults) and spread starts, no GA: much faster
};
// "ga" / "lm" (throws std::invalid_argument on anything else).
FitMethod fitMethodFromString(const std::string& s);
const char* toString(FitMethod m);
// What `pamc fit --method auto` runs: the multi-start search for the plain Bouc-Wen model (the GA's error
// at a tenth of the time), the GA when effects are added (an effect's parameters can have several
// basins, a saturation's knee, that the GA finds more surely).
FitMethod autoFitMethod(const model::Model& structure);

struct FitSettings {
  FitMethod method = FitMethod::Ga;
  GaSettings ga{};  // also the seed and the threads of the multi-start method
  bool refine = true;
  int refine_evals = 300;  // Nelder-Mead polish after Levenberg-Marquardt (non-smooth effects)
  int lm_iterations = 40;  // Levenberg-Marquardt iterations after the GA (0: none)
  // A Levenberg-Marquardt run ends when a step lowers the cost by less than this fraction of it.
  double lm_tolerance = 1e-10;
  // Levenberg-Marquardt's undamped check (levenbergMarquardt): a failed damped step is retried at the start's
  // damping, and a small gain at a grown damping is not convergence until that damping gained little too.
  bool lm_undamped_check = false;
  int lm_starts = 3;  // LM also from this many distinct runners-up of the GA (short runs)
  // ... and from this many points spread over the search box (Latin hypercube, seeded): a
  // multimodal fit (a hysteretic effect that can mirror the core's loop) is not left to the GA alone.
  int lm_spread_starts = 16;
  // With a start model: LM also from this many points that keep it and spread the parameters of the
  // effects it lacks over their ranges (Latin hypercube).
  int lm_warm_starts = 4;
  // Of each group of starts, the short runs of this many (the best) go on to the end.
  int lm_keep = 2;
  // With a start model: the parameters of the effects it has are held at its values; the core and the
  // effects it lacks are fitted (a probe on a model of many effects, to rank many probes quickly).
  bool hold_effects = false;
  // With a start model: the search box widened to hold its values where the record's own box does not.
  // The box scales with the record's range, so a model refitted on a record that covers less of the
  // stroke than the one it came from would start clamped (`pamc fit --start`).
  bool box_holds_start = false;

  // The defaults of a method: the GA's as above; the multi-start method with fewer spread starts
  // (6), more starts around a start model (8) and a shorter Nelder-Mead polish (100, none for the plain core), which on
  // the benchmark records reach the GA's error (docs/PERFORMANCE.md).
  static FitSettings forMethod(FitMethod m) {
    FitSettings s;
    s.method = m;
    if (m == FitMethod::MultiStart) {
      s.lm_spread_starts = 6;
      s.lm_warm_starts = 8;
      s.refine_evals = 100;
    }
    return s;
  }
};

struct FitResult {
  model::Model model;
  double mse = 0.0;
  double rmse = 0.0;
  int generations = 0;
  int evaluations = 0;
  double seconds = 0.0;
  // With box_holds_start: each parameter of the start that lay outside the record's own box, with that
  // box ("pneumatic_balance.delta 3 lies outside this record's box (0.00604 to 1.21)").
  std::vector<std::string> widened;
};

struct Bounds {
  std::vector<double> lo, hi;
};

// Bounds of the search, scaled to the ranges of u and y in the data (so the same search works on
// volts/millimetres or newtons/metres). The search vector is the model's parameter vector with
// (k, rho) replaced by (k rho, k (1 - rho)); alpha is fixed at 1 (see bouc_wen.hpp).
Bounds dataBounds(const model::Model& structure, const io::Measurement& data);

// `m` with its effects' weakly held parameters (Effect::weaklyHeld) at the catalogue's defaults, each scaled
// to the record by the factor its box is (dataBounds) and kept within that box; `names`, if given, says
// which ("pneumatic_balance's span, supply, b, n"). None where no effect of `m` has such parameters.
std::optional<model::Model> withWeakDefaults(const model::Model& m, const io::Measurement& data,
                                             std::string* names = nullptr);

// Search vector -> model parameter vector.
void searchToModel(const std::vector<double>& x, std::vector<double>& p);

// MSE of the model's simulated output against y.
double mse(const model::Model& m, const io::Measurement& data);

// Model parameter vector -> search vector.
std::vector<double> modelToSearch(const std::vector<double>& p);

// Fits the parameters of `structure` (its effects decide what is fitted) to the data.
// progress(stage, iteration, rmse) with stage "ga" or "refine". With `start`, the search is
// warm-started from it: its parameters seed half the population (effects it lacks are explored
// over their whole range).
FitResult fit(const model::Model& structure, const io::Measurement& data, const FitSettings& s,
              const std::function<void(const char*, int, double)>& progress = {}, const model::Model* start = nullptr);

// The record of a fit that a model file keeps under "fit" (`pamc fit --out`): the data's name, its
// samples and sampling step, the RMSE, the search's effort, its seed and method.
nlohmann::json fitReport(const FitResult& r, const FitSettings& s, const io::Measurement& data,
                         const std::string& source);

// RMSE of the model simulated on the whole record, scored over samples [from, n).
double rmseFrom(const model::Model& m, const io::Measurement& data, size_t from = 0);

}  // namespace pamc::ident
