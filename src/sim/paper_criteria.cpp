#include "sim/paper_criteria.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "io/text.hpp"

namespace pamc::sim {

namespace {

using io::fmt;

const char* const kCols[4] = {"open", "pi", "eso", "amc"};

}  // namespace

double jsonNumber(const nlohmann::json& j, std::initializer_list<const char*> path) {
  const nlohmann::json* p = &j;
  for (const char* k : path) {
    if (!p->is_object() || !p->contains(k)) return NAN;
    p = &(*p)[k];
  }
  return p->is_number() ? p->get<double>() : NAN;
}

namespace {
// jsonNumber that also clears `ok` when the entry is missing.
double num(const nlohmann::json& j, std::initializer_list<const char*> path, bool& ok) {
  const double v = jsonNumber(j, path);
  if (std::isnan(v)) ok = false;
  return v;
}
}  // namespace

std::vector<Criterion> paperCriteria(const nlohmann::json& s) {
  std::vector<Criterion> out;
  auto add = [&](const std::string& name, const std::string& claim, bool have, bool ok, const std::string& detail) {
    out.push_back({name, claim, have && ok, have, have ? detail : "not run"});
  };

  {  // Table 1: the reference model misses the plant by the paper's amount.
    bool have = true, ok = true;
    std::string d;
    const char* u[3] = {"u0", "u1", "u2"};
    for (int i = 0; i < 3; ++i) {
      const double v = num(s, {"table1", u[i], "reference_rmse"}, have);
      const double r = v / PaperNumbers::table1_reference[i];
      ok = ok && r <= 1.3 && r >= 1 / 1.3;
      d += std::string(i ? ", " : "") + u[i] + " " + fmt("%.2f", v) + fmt(" (%.2fx)", r);
    }
    add("table1_within_1.3x", "reference-model RMSE within 1.3x of Table 1", have, ok, d);
  }
  bool have2 = s.contains("table2");
  {  // Table 2 RMSE of the closed loops within 1.3x; triangle max within 1.5x.
    bool have = have2, ok = true, ok_max = true;
    std::string d, dm;
    for (int row = 0; row < 3; ++row)
      for (int c = 1; c < 4; ++c) {
        const double v = num(s, {"table2", PaperNumbers::table2_rows[row], kCols[c], "rmse"}, have);
        const double r = v / PaperNumbers::table2[row][c][1];
        ok = ok && r <= 1.3 && r >= 1 / 1.3;
        d += std::string(d.empty() ? "" : ", ") + kCols[c] + " " + fmt("%.2fx", r);
        if (row == 0) {
          const double m = num(s, {"table2", PaperNumbers::table2_rows[0], kCols[c], "max"}, have);
          const double rm = m / PaperNumbers::table2[0][c][0];
          ok_max = ok_max && rm <= 1.5 && rm >= 1 / 1.5;
          dm += std::string(dm.empty() ? "" : ", ") + kCols[c] + " " + fmt("%.2f", m) + fmt(" (%.2fx)", rm);
        }
      }
    add("table2_rmse_within_1.3x", "PI, ESO and AMC RMSE within 1.3x of Table 2 (ratios row by row)", have, ok, d);
    add("table2_triangle_max_within_1.5x", "triangle max errors within 1.5x of Table 2", have, ok_max, dm);
  }
  {  // Ordering: AMC < ESO < PI on every trajectory, and AMC < PI alone.
    bool have = have2, ok = true, ok_amc = true;
    std::string d;
    for (int row = 0; row < 3; ++row) {
      const double pi = num(s, {"table2", PaperNumbers::table2_rows[row], "pi", "rmse"}, have);
      const double eso = num(s, {"table2", PaperNumbers::table2_rows[row], "eso", "rmse"}, have);
      const double amc = num(s, {"table2", PaperNumbers::table2_rows[row], "amc", "rmse"}, have);
      ok = ok && amc < eso && eso < pi;
      ok_amc = ok_amc && amc < pi;
      d += std::string(row ? "; " : "") + fmt("%.3f", amc) + " / " + fmt("%.3f", eso) + " / " + fmt("%.3f", pi);
    }
    add("order_amc_below_pi", "PI + AMC tracks better than PI on all three trajectories", have, ok_amc,
        "AMC / ESO / PI RMSE " + d);
    add("order_amc_eso_pi", "RMSE ordering AMC < ESO < PI on all three trajectories", have, ok, "AMC / ESO / PI RMSE " + d);
  }
  {  // The sines' start transient (Figs. 8-9): PI overshoots and oscillates, AMC attenuates it. (The
     // paper's ESO attenuates it too; ours does not - docs/CALIBRATION.md - and the detail shows it.)
    bool have = have2, ok = true;
    std::string d;
    for (int row = 1; row < 3; ++row) {
      const double pi = num(s, {"table2", PaperNumbers::table2_rows[row], "pi", "max"}, have);
      const double eso = num(s, {"table2", PaperNumbers::table2_rows[row], "eso", "max"}, have);
      const double amc = num(s, {"table2", PaperNumbers::table2_rows[row], "amc", "max"}, have);
      ok = ok && amc < pi;
      d += std::string(row > 1 ? "; " : "") + fmt("%.2f", amc) + " / " + fmt("%.2f", eso) + " / " + fmt("%.2f", pi);
    }
    add("sines_amc_max_below_pi", "sines: AMC's max error below PI's (PI's start transient)", have, ok,
        "AMC / ESO / PI max " + d + " mm");
  }
  {  // Square wave, forward steps.
    bool have = s.contains("discontinuous");
    const double pi_os = num(s, {"discontinuous", "square", "forward", "pi", "overshoot_pct"}, have);
    const double amc_os = num(s, {"discontinuous", "square", "forward", "amc", "overshoot_pct"}, have);
    const double amc_ts = num(s, {"discontinuous", "square", "forward", "amc", "settling_s"}, have);
    const double amc_un = num(s, {"discontinuous", "square", "forward", "amc", "unsettled_steps"}, have);
    const double amc_x = num(s, {"discontinuous", "square", "forward", "amc", "max_error_crossings"}, have);
    const double amc_r = num(s, {"discontinuous", "square", "forward", "amc", "max_u_reversals"}, have);
    const double amc_xb = num(s, {"discontinuous", "square", "backward", "amc", "max_error_crossings"}, have);
    const double amc_rb = num(s, {"discontinuous", "square", "backward", "amc", "max_u_reversals"}, have);
    add("square_pi_overshoot_10_25", "square wave forward: PI overshoots 10-25 % (paper ~17 %)", have,
        pi_os >= 10 && pi_os <= 25, "PI " + fmt("%.1f %%", pi_os));
    add("square_amc_overshoot_half", "square wave forward: AMC overshoot at most half of PI's", have,
        amc_os <= 0.5 * pi_os, "AMC " + fmt("%.1f %%", amc_os) + " vs PI " + fmt("%.1f %%", pi_os));
    add("square_amc_settles_0.6s", "square wave forward: AMC settles (2 % band) within 0.6 s", have,
        amc_ts <= 0.6 && amc_un == 0, "AMC " + fmt("%.2f s", amc_ts));
    add("square_amc_no_ringing",
        "square wave forward: no ringing of the AMC (per step at most 2 error crossings of a 1 % band, at most 3 "
        "reversals of the 20 Hz low-passed valve command by > 0.05 V)",
        have, amc_x <= 2 && amc_r <= 3,
        "forward " + fmt("%.0f", amc_x) + " crossings / " + fmt("%.0f", amc_r) + " reversals, backward " + fmt("%.0f", amc_xb) +
            " / " + fmt("%.0f", amc_rb));
  }
  {  // Payload: AMC has the smallest peak and the shortest recovery.
    bool have = s.contains("payload");
    double pk[3], rc[3];
    const char* k[3] = {"pi", "eso", "amc"};
    for (int i = 0; i < 3; ++i) {
      pk[i] = num(s, {"payload", k[i], "peak_deviation_mm"}, have);
      rc[i] = num(s, {"payload", k[i], "recovery_s"}, have);
    }
    add("payload_amc_best", "payload 40 N: AMC has the smallest peak deviation and the shortest recovery", have,
        pk[2] <= std::min(pk[0], pk[1]) && rc[2] <= std::min(rc[0], rc[1]),
        "peak PI/ESO/AMC " + fmt("%.2f", pk[0]) + "/" + fmt("%.2f", pk[1]) + "/" + fmt("%.2f mm", pk[2]) + ", recovery " +
            fmt("%.2f", rc[0]) + "/" + fmt("%.2f", rc[1]) + "/" + fmt("%.2f s", rc[2]));
  }
  return out;
}

std::string formatCriteria(const std::vector<Criterion>& c) {
  std::string t;
  for (const auto& x : c) {
    t += std::string("  [") + (!x.checked ? " -- " : x.ok ? " ok " : "MISS") + "] " + x.claim + ": " + x.detail + "\n";
  }
  return t;
}

int criteriaMet(const std::vector<Criterion>& c) {
  return static_cast<int>(std::count_if(c.begin(), c.end(), [](const Criterion& x) { return x.ok; }));
}

}  // namespace pamc::sim
