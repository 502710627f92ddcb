// Where a model fails: the residual e = y - y_model broken down by where it happens, and the
// residual tests of system identification (auto-correlation of e, cross-correlation of e with the
// input) with confidence bounds, plus the indicators that point at physical effects.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "io/measurement.hpp"

namespace pamc::diagnose {

struct Bin {
  std::string group;  // "direction", "turning point", "input level", "input rate", "hold", "load", "output level"
  std::string label;
  size_t n = 0;
  double rmse = 0, mean = 0;
};

struct ResidualReport {
  size_t n = 0;
  double rmse = 0, max_abs = 0, fit_pct = 0, mean = 0;
  double noise_floor = 0;  // estimated sensor noise of y (rms), from its second differences
  std::vector<Bin> bins;
  int max_lag = 0;             // lags 0..max_lag (auto), -max_lag..max_lag (cross)
  double lag_step_s = 0;       // seconds per lag
  std::vector<double> acf;     // residual auto-correlation
  std::vector<double> ccf_du;  // corr(e(t), du(t - lag)) for lag = -max_lag..max_lag
  double conf = 0;             // 95 % bound: 1.96 / sqrt(n)
  // Indicators used as evidence for effects (see effectEvidence).
  std::map<std::string, double> ind;
};

// y_model simulated on the measurement's own input.
ResidualReport analyze(const io::Measurement& d, const std::vector<double>& y_model);

// The signs in the residual that point at an effect, in one line, and a strength in [0, 1].
struct Evidence {
  std::string text;
  double strength = 0;
};
Evidence effectEvidence(const std::string& effect, const ResidualReport& r);

// The breakdown as a text table.
std::string formatReport(const ResidualReport& r);

// How an offset between a model and a record runs over the record: its mean over the record's first tenth
// and over its second half. Records that start in different states (a sensor zero moved, a warm-up already
// under way) show the offset from the first samples on; a model that settles elsewhere than the muscle on
// the record's input (a loop of the hysteresis the training record did not hold) comes to it over the
// record.
struct OffsetCourse {
  double head = 0.0, tail = 0.0;  // mean of e over the first tenth, over the second half
  // The offset builds up: its second half's mean at least twice its first tenth's (or of the other sign).
  bool buildsUp() const noexcept { return tail != 0.0 && head * tail < 0.5 * tail * tail; }
};
OffsetCourse offsetCourse(const double* e, size_t n);

}  // namespace pamc::diagnose
