// fuzz_csv: measurement CSV text through parseMeasurementCsv (what readMeasurementCsv runs on a file).
// Documented error: io::InputError, one line starting with the source name. An accepted file must be
// usable: at least 3 rows, equal column lengths, finite values within the reader's limits (|t| <=
// kMaxTime, other columns within +-kMaxDataValue), time strictly increasing with a finite step of at
// least kMinSamplingStep.
#include <cmath>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "io/measurement.hpp"

using pamc::fuzz::finding;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  pamc::io::Measurement m;
  std::vector<std::string> warnings;
  try {
    m = pamc::io::parseMeasurementCsv(text, "fuzz.csv", &warnings);
  } catch (const pamc::io::InputError& e) {
    pamc::fuzz::checkMessage(e.what(), "fuzz.csv");
    return 0;
  }
  for (const auto& w : warnings) pamc::fuzz::checkMessage(w.c_str(), "fuzz.csv");
  const std::size_t n = m.size();
  if (n < 3) finding("accepted a measurement of " + std::to_string(n) + " rows");
  if (m.u.size() != n || m.y.size() != n) finding("columns t, u, y of different lengths");
  auto finite = [&](const std::vector<double>& v, const std::string& name, double limit) {
    for (double x : v) {
      if (!std::isfinite(x)) finding("column " + name + " holds a value that is not finite");
      if (std::fabs(x) > limit) finding("column " + name + " holds a value beyond the limit");
    }
  };
  finite(m.t, "t", pamc::io::kMaxTime);
  finite(m.u, "u", pamc::io::kMaxDataValue);
  finite(m.y, "y", pamc::io::kMaxDataValue);
  for (const auto& [name, col] : m.extra) {
    if (col.size() != n) finding("column " + name + " has another length than t");
    finite(col, name, pamc::io::kMaxDataValue);
  }
  for (std::size_t i = 1; i < n; ++i) {
    if (!(m.t[i] > m.t[i - 1])) finding("time does not increase");
  }
  if (!std::isfinite(m.Ts) || !(m.Ts >= pamc::io::kMinSamplingStep))
    finding("sampling step Ts = " + std::to_string(m.Ts));
  const pamc::io::Measurement half = m.slice(n / 2, n);
  if (half.size() != n - n / 2 || half.u.size() != half.size()) finding("slice has the wrong size");
  return 0;
}
