// Three of diagnose's search rules, kept apart from the fits they steer so that each is read and tested
// on its own (tests/unit/test_search_rules.cpp): the walk along a richer form's direction
// (Diagnosis::searchAlong), what becomes of a richer form's fit (Diagnosis::refineOne) and whether the
// screening record can resolve the final model for the probes (Diagnosis::screenResolves).
#pragma once

namespace pamc::diagnose {

// searchAlong's walk: steps of the pressure's force by `step` (kStep up, 1 / kStep down), each started
// from the last point that kept the basin. A step whose run ends above kLost times the training RMSE of
// the point it started from has lost it: the point stays, and the next start is one step further along
// from it. The walk found a basin when a point it kept trains at 1 / kLost of the quick fit's error or
// below.
class AlongPath {
 public:
  static constexpr double kStep = 1.26;
  static constexpr int kSteps = 6;      // up: to 4 times the quick fit's force
  static constexpr int kStepsDown = 3;  // down: to half of it
  static constexpr double kLost = 2.0;

  explicit AlongPath(double start_train, double step = kStep)
      : start_train_(start_train), at_train_(start_train), best_train_(start_train), step_(step), ahead_(step) {}

  // How far along from the current point the next step starts.
  double ahead() const noexcept { return ahead_; }
  // The force of the step about to run (or just run), over the quick fit's.
  double scale() const noexcept { return scale_; }
  // A step is about to run (ahead() from the current point).
  void begin() noexcept { scale_ *= step_; }
  // The step's run ended at this training RMSE: false when it lost the basin (the point stays).
  bool end(double train) noexcept {
    if (train > kLost * at_train_) {
      ahead_ *= step_;
      return false;
    }
    at_train_ = train;
    best_train_ = train < best_train_ ? train : best_train_;
    ahead_ = step_;
    return true;
  }
  bool foundBasin() const noexcept { return kLost * best_train_ <= start_train_; }

 private:
  double start_train_, at_train_, best_train_;
  double step_;
  double scale_ = 1.0;
  double ahead_;
};

// What becomes of a richer form's fit against the rung it would replace (Diagnosis::refineOne): taken
// into the ladder when it lowers the validated RMSE by min_gain; looked past (Diagnosis::lookAhead: its
// own richer forms tried from its fit) when it lowers only the training RMSE by min_gain; else dropped.
enum class Refinement { Dropped, Taken, LookPast };

inline bool gainsBy(double now, double was, double min_gain) noexcept { return 1.0 - now / was >= min_gain; }

inline Refinement judgeRefinement(double train, double val, double rung_train, double rung_val,
                                  double min_gain) noexcept {
  if (gainsBy(val, rung_val, min_gain)) return Refinement::Taken;
  return gainsBy(train, rung_train, min_gain) ? Refinement::LookPast : Refinement::Dropped;
}

// Why the probes are not fitted on the screening record, or None.
enum class ScreenVerdict {
  None,
  Moves,      // decimation moves the final model's own output by more than what is left of the training
  NullProbe,  // the final structure, fitted there as a probe is, validates worse by more than min_gain
};

// moved: the final model's output on the screening record against the full one (rms); train, val: its
// training and validated RMSE; null_val() its null probe's validated RMSE, asked only where needed (a fit).
template <class NullProbe>
ScreenVerdict screenVerdict(double moved, double train, double val, double min_gain, NullProbe null_val) {
  if (moved > train) return ScreenVerdict::Moves;
  if (!(moved > min_gain * train)) return ScreenVerdict::None;  // the screening hardly moves it
  return null_val() > (1.0 + min_gain) * val ? ScreenVerdict::NullProbe : ScreenVerdict::None;
}

}  // namespace pamc::diagnose
