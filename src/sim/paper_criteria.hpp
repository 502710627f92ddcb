// What the paper shows, as checks on an experiment summary (the JSON of runExperiments): the
// criteria the default run is calibrated to (docs/CALIBRATION.md) and that the tests guard.
// One table, so the calibration, the `experiments` summary and the tests judge alike.
#pragma once

#include <initializer_list>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace pamc::sim {

struct Criterion {
  std::string name;    // short, stable: "table2_rmse_within_1.3x", "order_amc_eso_pi", ...
  std::string claim;   // the paper's claim in words
  bool ok = false;
  bool checked = false;  // false when the summary lacks the section (e.g. --only)
  std::string detail;  // the measured figures behind the verdict
};

std::vector<Criterion> paperCriteria(const nlohmann::json& summary);

// The number at a path of keys in a summary; NaN where the path or the number is missing.
double jsonNumber(const nlohmann::json& j, std::initializer_list<const char*> path);

// The table as text, one line per criterion; and how many of the checked ones hold.
std::string formatCriteria(const std::vector<Criterion>& c);
int criteriaMet(const std::vector<Criterion>& c);

// The paper's reference numbers (Tables 1 and 2), one place for them.
struct PaperNumbers {
  static constexpr double table1_reference[3] = {2.012, 3.687, 2.284};  // u0, u1, u2 RMSE [mm]
  // Table 2, max / RMSE [mm], rows triangle 0.05 Hz, sine 0.05 Hz, sine 0.1 Hz; columns open, PI, ESO, AMC.
  static constexpr const char* table2_rows[3] = {"triangle_0.05Hz", "sine_0.05Hz", "sine_0.1Hz"};
  static constexpr double table2[3][4][2] = {
      {{10.978, 6.395}, {1.097, 0.3461}, {1.100, 0.3243}, {0.924, 0.3209}},
      {{10.357, 6.873}, {3.769, 0.2450}, {2.322, 0.2005}, {1.323, 0.1934}},
      {{10.046, 6.592}, {3.272, 0.4670}, {2.010, 0.3911}, {1.922, 0.3803}}};
};

}  // namespace pamc::sim
