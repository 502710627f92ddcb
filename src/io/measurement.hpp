// Measurement files: CSV with a header naming at least t,u,y (seconds, command, position in
// the file's own units) and any further columns (load, p, ...).
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace pamc::io {

// One-line error naming the place: "file:line:column: problem".
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Measurement {
  std::string source;
  std::vector<double> t, u, y;
  std::map<std::string, std::vector<double>> extra;  // further columns by header name
  double Ts = 0.0;                                   // sampling step read from the time column

  size_t size() const { return t.size(); }
  bool has(const std::string& col) const { return extra.count(col) > 0; }
  const std::vector<double>* column(const std::string& col) const {
    auto it = extra.find(col);
    return it == extra.end() ? nullptr : &it->second;
  }
  // Sub-range [begin, end) as a new measurement.
  Measurement slice(size_t begin, size_t end) const;
  // Every `step`-th sample from the first (step >= 1), with the sampling step step * Ts: the whole
  // record at a lower rate.
  Measurement decimate(size_t step) const;
};

// Limits of the data a measurement may hold; the one place for them, enforced by parseMeasurementCsv.
// Data columns (u, y, load, ... - everything but t) within +-kMaxDataValue: far beyond any command or
// sensor in any sensible unit, and small enough that what fit, diagnose and compare derive from the
// data (ranges, parameter bounds scaled by them, differences, squared errors) stays finite - with
// values near 1e308 the ranges overflowed and the identification crashed. Time within +-kMaxTime
// seconds (a finite span and step) and a sampling step of at least kMinSamplingStep seconds (finite
// rates |du| / Ts).
constexpr double kMaxDataValue = 1e9;
constexpr double kMaxTime = 1e12;
constexpr double kMinSamplingStep = 1e-9;

// Reads and validates a measurement CSV; throws InputError. What it tolerates (a truncated last line,
// dropped) is appended to warnings, one line each, when given - the same convention everywhere in pamc.
Measurement readMeasurementCsv(const std::string& path, std::vector<std::string>* warnings = nullptr);
// Parses CSV text (source names it in errors).
Measurement parseMeasurementCsv(const std::string& text, const std::string& source,
                                std::vector<std::string>* warnings = nullptr);

// Writes columns as CSV atomically: the file appears complete or not at all (see writeFileAtomic).
// Throws std::runtime_error.
void writeCsvAtomic(const std::string& path, const std::vector<std::string>& header,
                    const std::vector<const std::vector<double>*>& columns, int precision = 9);
// Writes a text file atomically: written into an unnamed file in the target's directory (O_TMPFILE),
// synced, and linked or renamed into place when complete, so a crash or kill -9 leaves either the old
// file or the new one, never a half-written file and (but for the instant between link and rename when
// a file is replaced) no temporary. Falls back to a named temporary PATH.tmp.PID where O_TMPFILE is
// not supported.
void writeFileAtomic(const std::string& path, const std::string& content);
// Creates the folder `dir` if it is missing (its parent must exist); throws std::runtime_error
// "<dir>: cannot create the <what>" when it is not a folder afterwards.
void makeDirectory(const std::string& dir, const std::string& what = "output directory");

}  // namespace pamc::io
