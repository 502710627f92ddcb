// Every claim of the paper's Sections 5.2-6 and Tables 1-2, in one table, each with the threshold it
// takes from the paper's words and its role: calibrated (the plant and the reading of ki are fitted to
// it: Table 1 and Table 2's triangle row, what the paper tuned on) or predicted (everything else).
// `pamc experiments` fills in the run's value and a verdict; `pamc calibrate` reads the calibrated rows
// only (calibrationDistance). docs/EXPERIMENTS.md explains the thresholds.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace pamc::sim {

enum class ClaimRole { Calibrated, Predicted };

// How a claim is checked on a summary. Paths are '/'-separated keys into the summary JSON.
struct ClaimTest {
  enum class Kind {
    Near,    // value at a[0] within a factor `factor` of `paper` (both directions)
    Range,   // value at a[0] in [lo, hi]
    AtMost,  // every value at a[] at most hi (the value shown: the largest)
    Below,   // every value at a[] below factor * every value at b[] (the value shown: the largest of a)
    Spread,  // the values at a[] within a factor `factor` of each other (largest / smallest)
  };
  Kind kind = Kind::Near;
  std::vector<std::string> a, b;
  double paper = 0, factor = 1, lo = 0, hi = 0;
};

struct Claim {
  std::string id;     // stable: "t2_sine05_amc_rmse", ...
  std::string where;  // "Table 2", "Sec. 5.5, Fig. 10a", ...
  std::string claim;  // the paper's claim in words
  std::string paper;  // the paper's figure or words
  ClaimRole role = ClaimRole::Predicted;
  ClaimTest test;
};

// The table (one place for it).
const std::vector<Claim>& paperClaims();

// The threshold of a claim in words, from its test ("within 1.3x of 0.245", "<= 2", ...).
std::string thresholdText(const ClaimTest& t);

enum class Verdict { NotRun, Calibrated, Reproduced, NotReproduced };
const char* toString(Verdict v);

struct ClaimResult {
  const Claim* claim = nullptr;
  double value = 0;        // the run's figure (NaN when not run)
  std::string value_text;  // with the compared figures where the test has several
  bool holds = false;      // the threshold is met (also for calibrated rows: whether the fit reached it)
  Verdict verdict = Verdict::NotRun;
};

// Judges every claim on an experiments summary.
std::vector<ClaimResult> judgeClaims(const nlohmann::json& summary, const std::vector<Claim>& claims = paperClaims());

struct ClaimCount {
  int predicted = 0, reproduced = 0, calibrated = 0, calibrated_held = 0, not_run = 0;
};
ClaimCount countClaims(const std::vector<ClaimResult>& r);

// The table as text (one line per claim) and as JSON [{id, claim, where, paper, value, threshold, verdict}].
std::string formatClaims(const std::vector<ClaimResult>& r);
nlohmann::json claimsJson(const std::vector<ClaimResult>& r);
// The table itself as Markdown (no run): id, where, claim, paper, threshold, role.
std::string claimsMarkdown(const std::vector<Claim>& claims = paperClaims());

// The calibration's objective: mean |ln(ours / paper)| over the calibrated Near rows (Table 1 and the
// triangle row). It reads no predicted row (a test changes them all and checks the choice stays).
double calibrationDistance(const nlohmann::json& summary, const std::vector<Claim>& claims = paperClaims());

// The number at a '/'-separated path in a summary; NaN where the path or the number is missing.
double numberAt(const nlohmann::json& j, const std::string& path);

// The paper's reference numbers (Tables 1 and 2), one place for them.
struct PaperNumbers {
  static constexpr double table1_reference[3] = {2.012, 3.687, 2.284};  // u0, u1, u2 RMSE [mm]
  static constexpr double table1_active[3] = {1.482e-4, 1.379e-4, 1.397e-4};
  // Table 2, max / RMSE [mm], rows triangle 0.05 Hz, sine 0.05 Hz, sine 0.1 Hz; columns open, PI, ESO, AMC.
  static constexpr const char* table2_rows[3] = {"triangle_0.05Hz", "sine_0.05Hz", "sine_0.1Hz"};
  static constexpr const char* table2_cols[4] = {"open", "pi", "eso", "amc"};
  static constexpr double table2[3][4][2] = {{{10.978, 6.395}, {1.097, 0.3461}, {1.100, 0.3243}, {0.924, 0.3209}},
                                             {{10.357, 6.873}, {3.769, 0.2450}, {2.322, 0.2005}, {1.323, 0.1934}},
                                             {{10.046, 6.592}, {3.272, 0.4670}, {2.010, 0.3911}, {1.922, 0.3803}}};
};

}  // namespace pamc::sim
