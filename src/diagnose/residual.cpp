#include "diagnose/residual.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <sstream>

#include <Eigen/Core>

#include "io/text.hpp"

namespace pamc::diagnose {

namespace {

double rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? 0 : std::sqrt(s / static_cast<double>(v.size()));
}

// Correlation of a[0..n) and b[0..n).
double corr(const double* a, const double* b, size_t n) {
  if (n <= 2) return 0;
  const auto N = static_cast<Eigen::Index>(n);
  const Eigen::Map<const Eigen::ArrayXd> A(a, N), B(b, N);
  const Eigen::ArrayXd ac = A - A.mean(), bc = B - B.mean();
  const double sab = (ac * bc).sum(), saa = ac.square().sum(), sbb = bc.square().sum();
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

double corr(const std::vector<double>& a, const std::vector<double>& b, size_t from = 0) {
  const size_t n = std::min(a.size(), b.size());
  return n <= from ? 0.0 : corr(a.data() + from, b.data() + from, n - from);
}

std::vector<double> quantiles(std::vector<double> v, std::initializer_list<double> qs) {
  std::vector<double> out;
  if (v.empty()) return std::vector<double>(qs.size(), 0.0);
  std::sort(v.begin(), v.end());
  for (double q : qs) out.push_back(v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))]);
  return out;
}

struct Acc {
  size_t n = 0;
  double s = 0, ss = 0;
  void add(double e) {
    ++n;
    s += e;
    ss += e * e;
  }
  double rmse() const { return n ? std::sqrt(ss / static_cast<double>(n)) : 0.0; }
  double mean() const { return n ? s / static_cast<double>(n) : 0.0; }
};

using io::fmt;

}  // namespace

ResidualReport analyze(const io::Measurement& d, const std::vector<double>& yhat) {
  ResidualReport r;
  const size_t n = std::min(d.size(), yhat.size());
  r.n = n;
  if (n < 4) return r;
  std::vector<double> e(n);
  for (size_t i = 0; i < n; ++i) e[i] = d.y[i] - yhat[i];
  r.rmse = rms(e);
  double ym = 0;
  for (size_t i = 0; i < n; ++i) {
    r.max_abs = std::max(r.max_abs, std::fabs(e[i]));
    r.mean += e[i];
    ym += d.y[i];
  }
  r.mean /= static_cast<double>(n);
  ym /= static_cast<double>(n);
  double sy = 0;
  for (size_t i = 0; i < n; ++i) sy += (d.y[i] - ym) * (d.y[i] - ym);
  r.fit_pct = sy > 0 ? 100.0 * (1.0 - r.rmse * std::sqrt(static_cast<double>(n)) / std::sqrt(sy)) : 0.0;
  // Sensor noise from second differences (robust: median absolute value).
  {
    std::vector<double> d2;
    d2.reserve(n);
    for (size_t i = 2; i < n; ++i) d2.push_back(std::fabs(d.y[i] - 2 * d.y[i - 1] + d.y[i - 2]));
    std::nth_element(d2.begin(), d2.begin() + static_cast<long>(d2.size() / 2), d2.end());
    r.noise_floor = 1.4826 * d2[d2.size() / 2] / std::sqrt(6.0);
  }
  const double Ts = d.Ts;
  const auto [umin_it, umax_it] = std::minmax_element(d.u.begin(), d.u.begin() + static_cast<long>(n));
  const double ru = std::max(*umax_it - *umin_it, 1e-12);
  std::vector<double> du(n, 0.0);
  for (size_t i = 1; i < n; ++i) du[i] = d.u[i] - d.u[i - 1];
  const double eps = 1e-9 * ru;

  // Direction, turning points and holds.
  Acc rising, falling, holding, near_turn, away_turn;
  std::vector<double> hold_time(n, 0.0);
  int dir = 0;
  double u_rev = d.u[0], u_anchor = d.u[0], t_anchor = 0;
  std::vector<int> dirv(n, 0);
  for (size_t i = 0; i < n; ++i) {
    const int s = du[i] > eps ? 1 : du[i] < -eps ? -1 : 0;
    if (s != 0 && s != dir) {
      if (dir != 0) u_rev = d.u[i - 1];
      dir = s;
    }
    dirv[i] = s;
    if (std::fabs(d.u[i] - u_anchor) > 0.002 * ru) {
      u_anchor = d.u[i];
      t_anchor = static_cast<double>(i) * Ts;
    }
    hold_time[i] = static_cast<double>(i) * Ts - t_anchor;
    (s > 0 ? rising : s < 0 ? falling : holding).add(e[i]);
    (std::fabs(d.u[i] - u_rev) < 0.1 * ru && dir != 0 ? near_turn : away_turn).add(e[i]);
  }
  auto push = [&](const std::string& g, const std::string& l, const Acc& a) {
    if (a.n) r.bins.push_back({g, l, a.n, a.rmse(), a.mean()});
  };
  push("direction", "rising input", rising);
  push("direction", "falling input", falling);
  push("direction", "input held", holding);
  push("turning point", "within 10 % of travel after a reversal", near_turn);
  push("turning point", "further from a reversal", away_turn);

  // Quartile bins of a signal.
  auto quartileBins = [&](const std::string& group, const std::vector<double>& v, const std::vector<bool>* mask,
                          const char* unit) {
    std::vector<double> sel;
    for (size_t i = 0; i < n; ++i)
      if (!mask || (*mask)[i]) sel.push_back(v[i]);
    if (sel.size() < 8) return std::vector<Acc>{};
    const auto q = quantiles(sel, {0.25, 0.5, 0.75});
    std::vector<Acc> acc(4);
    for (size_t i = 0; i < n; ++i) {
      if (mask && !(*mask)[i]) continue;
      const int b = v[i] <= q[0] ? 0 : v[i] <= q[1] ? 1 : v[i] <= q[2] ? 2 : 3;
      acc[static_cast<size_t>(b)].add(e[i]);
    }
    const char* names[] = {"lowest quarter", "second quarter", "third quarter", "highest quarter"};
    for (int b = 0; b < 4; ++b) {
      std::string label = names[b];
      label += b == 0   ? " (<= " + fmt("%.4g", q[0]) + unit + ")"
               : b == 3 ? " (> " + fmt("%.4g", q[2]) + unit + ")"
                        : "";
      push(group, label, acc[static_cast<size_t>(b)]);
    }
    return acc;
  };
  const auto lvl = quartileBins("input level", d.u, nullptr, "");
  const auto out = quartileBins("output level", d.y, nullptr, "");
  std::vector<double> rate(n);
  std::vector<bool> moving(n);
  for (size_t i = 0; i < n; ++i) {
    rate[i] = std::fabs(du[i]) / Ts;
    moving[i] = dirv[i] != 0;
  }
  const auto rt = quartileBins("input rate", rate, &moving, "/s");
  // Holds: time since the input last moved by 0.2 % of its range.
  {
    const double edges[] = {0.05, 0.5, 2.0, 10.0};
    const char* labels[] = {"moving (< 0.05 s since)", "0.05-0.5 s since the input moved", "0.5-2 s", "2-10 s",
                            "> 10 s"};
    std::vector<Acc> acc(5);
    for (size_t i = 0; i < n; ++i) {
      int b = 0;
      while (b < 4 && hold_time[i] >= edges[b]) ++b;
      acc[static_cast<size_t>(b)].add(e[i]);
    }
    for (int b = 0; b < 5; ++b) push("hold", labels[b], acc[static_cast<size_t>(b)]);
  }
  const auto* load = d.column("load");
  if (load) {
    quartileBins("load", *load, nullptr, "");
    r.ind["corr_e_load"] = corr(e, *load);
  }

  // Residual tests over lags.
  r.conf = 1.96 / std::sqrt(static_cast<double>(n));
  r.max_lag = static_cast<int>(std::min<size_t>(n / 4, 250));
  r.lag_step_s = Ts;
  {
    // Each lag's sum as one vectorised product over the overlap of the centred series.
    const auto N = static_cast<Eigen::Index>(n);
    const Eigen::VectorXd ec = Eigen::Map<const Eigen::VectorXd>(e.data(), N).array() - r.mean;
    const Eigen::Map<const Eigen::VectorXd> dv(du.data(), N);
    const Eigen::VectorXd dc = dv.array() - dv.mean();
    const double v0 = ec.squaredNorm(), vd = dc.squaredNorm();
    r.acf.resize(static_cast<size_t>(r.max_lag) + 1);
    for (int L = 0; L <= r.max_lag; ++L)
      r.acf[static_cast<size_t>(L)] = v0 > 0 ? ec.tail(N - L).dot(ec.head(N - L)) / v0 : 0;
    // corr(e(i), du(i - L)): for L >= 0 the pairs (i, i - L), i >= L; for L < 0, i < n + L.
    r.ccf_du.resize(2 * static_cast<size_t>(r.max_lag) + 1);
    for (int L = -r.max_lag; L <= r.max_lag; ++L) {
      const Eigen::Index m = N - std::abs(L);
      const double sum = L >= 0 ? ec.tail(m).dot(dc.head(m)) : ec.head(m).dot(dc.tail(m));
      r.ccf_du[static_cast<size_t>(L + r.max_lag)] = v0 > 0 && vd > 0 ? sum / std::sqrt(v0 * vd) : 0;
    }
  }

  // Indicators.
  r.ind["corr_e_du"] = corr(e, du);
  {
    // Residual against the output's own motion (friction acts on it).
    std::vector<double> dy(n, 0.0);
    for (size_t i = 1; i < n; ++i) dy[i] = yhat[i] - yhat[i - 1];
    r.ind["corr_e_dyhat"] = corr(e, dy);
  }
  auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  r.ind["turn_ratio"] = ratio(near_turn.rmse(), away_turn.rmse());
  r.ind["dir_mean_diff"] = r.rmse > 0 ? (rising.mean() - falling.mean()) / r.rmse : 0;
  if (rt.size() == 4) r.ind["rate_ratio"] = ratio(rt[3].rmse(), rt[0].rmse());
  if (lvl.size() == 4) r.ind["low_input_ratio"] = ratio(lvl[0].rmse(), 0.5 * (lvl[1].rmse() + lvl[2].rmse()));
  if (out.size() == 4) r.ind["high_output_ratio"] = ratio(out[3].rmse(), 0.5 * (out[1].rmse() + out[2].rmse()));
  // Creep: how far e moves during holds longer than 1 s, relative to the RMSE.
  {
    double drift = 0;
    int holds = 0;
    size_t i = 0;
    while (i < n) {
      if (hold_time[i] < 0.2) {
        ++i;
        continue;
      }
      const size_t a = i;
      while (i < n && hold_time[i] >= 0.2) ++i;
      if (static_cast<double>(i - a) * Ts >= 1.0) {
        // Mean of the last and first 10 % of the hold.
        const size_t m = std::max<size_t>(1, (i - a) / 10);
        double s0 = 0, s1 = 0;
        for (size_t k = 0; k < m; ++k) s0 += e[a + k], s1 += e[i - 1 - k];
        drift += std::fabs(s1 - s0) / static_cast<double>(m);
        ++holds;
      }
    }
    r.ind["hold_drift"] = holds && r.rmse > 0 ? drift / holds / r.rmse : 0.0;
    r.ind["holds"] = holds;
  }
  // Ringing: the auto-correlation's first minimum after it first falls below zero.
  {
    double mn = 0;
    int at = 0;
    bool below = false;
    for (size_t L = 1; L < r.acf.size(); ++L) {
      if (r.acf[L] < 0) below = true;
      if (below && r.acf[L] < mn) {
        mn = r.acf[L];
        at = static_cast<int>(L);
      }
      if (below && r.acf[L] > 0) break;
    }
    r.ind["ring_min"] = mn;
    r.ind["ring_hz"] = at > 0 ? 1.0 / (2.0 * at * Ts) : 0.0;
  }
  // Shift that best aligns the model with the data (delay evidence).
  {
    double best = -2;
    int at = 0;
    const int maxs = static_cast<int>(std::min<size_t>(n / 4, 250));
    for (int s = 0; s <= maxs; s += std::max(1, maxs / 100)) {
      const double c = corr(d.y.data() + s, yhat.data(), n - static_cast<size_t>(s));
      if (c > best) best = c, at = s;
    }
    r.ind["best_shift_s"] = at * Ts;
    r.ind["shift_gain"] = best - corr(d.y.data(), yhat.data(), n);
  }
  return r;
}

Evidence effectEvidence(const std::string& effect, const ResidualReport& r) {
  auto get = [&](const char* k) {
    auto it = r.ind.find(k);
    return it == r.ind.end() ? 0.0 : it->second;
  };
  auto clamp01 = [](double x) { return std::max(0.0, std::min(1.0, x)); };
  Evidence ev;
  if (effect == "pressure_lag") {
    const double c = get("corr_e_du"), rr = get("rate_ratio");
    ev.strength = clamp01(std::fabs(c) * 2 + (rr - 1) / 4);
    ev.text = "residual follows the input rate (corr(e, du/dt) = " + fmt("%.2f", c) + ") and is " + fmt("%.1f", rr) +
              "x larger at the fastest quarter of input rates than the slowest: the loop widens with rate";
  } else if (effect == "delay") {
    const double s = get("best_shift_s"), g = get("shift_gain");
    ev.strength = clamp01(g * 50 + (s > 0 ? 0.2 : 0));
    ev.text = "the model matches best when shifted " + fmt("%.4g", s * 1e3) + " ms later (correlation +" +
              fmt("%.4f", g) + "); the residual leads the input rate (corr = " + fmt("%.2f", get("corr_e_du")) + ")";
  } else if (effect == "creep") {
    const double h = get("hold_drift");
    ev.strength = clamp01(h);
    ev.text = get("holds") > 0 ? "the residual keeps drifting during holds: by " + fmt("%.2f", h) +
                                     " RMSE on average over " + fmt("%.0f", get("holds")) + " holds of >= 1 s"
                               : "no holds of >= 1 s in the data, so creep cannot show";
  } else if (effect == "mass_spring") {
    const double m = get("ring_min"), f = get("ring_hz");
    ev.strength = clamp01(-m * 2);
    ev.text = m < -0.05 ? "the residual auto-correlation swings to " + fmt("%.2f", m) + ": it rings near " +
                              fmt("%.3g", f) + " Hz after fast changes"
                        : "no ringing in the residual (its auto-correlation does not swing negative within the lags)";
  } else if (effect == "force_loop") {
    const double m = get("ring_min"), t = get("turn_ratio");
    ev.strength = clamp01(std::max(-m * 2, 0.0) + std::max((t - 1) / 4, 0.0));
    ev.text = "ringing (residual auto-correlation down to " + fmt("%.2f", m) + ") together with " + fmt("%.1f", t) +
              "x the error near turning points: a moving payload that sticks at reversals";
  } else if (effect == "friction_hysteresis") {
    const double t = get("turn_ratio");
    ev.strength = clamp01((t - 1) / 2);
    ev.text = "error near turning points is " + fmt("%.1f", t) +
              "x the error elsewhere (corr with the model's own motion " + fmt("%.2f", get("corr_e_dyhat")) + ")";
  } else if (effect == "asymmetry") {
    const double dd = get("dir_mean_diff");
    ev.strength = clamp01(std::fabs(dd));
    ev.text = "mean residual differs between rising and falling input by " + fmt("%.2f", dd) + " RMSE";
  } else if (effect == "dead_band") {
    const double l = get("low_input_ratio");
    ev.strength = clamp01((l - 1) / 2);
    ev.text = "error at the lowest quarter of input levels is " + fmt("%.1f", l) + "x the mid-range error";
  } else if (effect == "saturation") {
    const double h = get("high_output_ratio");
    ev.strength = clamp01((h - 1) / 2);
    ev.text = "error at the highest quarter of output levels is " + fmt("%.1f", h) + "x the mid-range error";
  } else if (effect == "load") {
    if (r.ind.count("corr_e_load")) {
      const double c = get("corr_e_load");
      ev.strength = clamp01(std::fabs(c) * 2);
      ev.text = "the residual follows the load column (corr = " + fmt("%.2f", c) + ")";
    } else {
      ev.text = "no load column in the data";
    }
  } else {
    ev.text = "no residual signature defined for this effect";
  }
  return ev;
}

std::string formatReport(const ResidualReport& r) {
  std::ostringstream o;
  o << "RMSE " << fmt("%.5g", r.rmse) << ", max |error| " << fmt("%.5g", r.max_abs) << ", fit "
    << fmt("%.2f", r.fit_pct) << " %, mean error " << fmt("%.3g", r.mean) << " (sensor noise estimated at "
    << fmt("%.3g", r.noise_floor) << " rms)\n\n";
  o << "Where the error is (RMSE and mean of y - model per group):\n";
  std::string last;
  for (const auto& b : r.bins) {
    if (b.group != last) o << "  " << b.group << "\n";
    last = b.group;
    char line[200];
    std::snprintf(line, sizeof line, "    %-42s n=%-8zu rmse %-10.4g mean %+.4g\n", b.label.c_str(), b.n, b.rmse,
                  b.mean);
    o << line;
  }
  // Residual tests: where they leave the 95 % band.
  int acf_out = 0, ccf_out = 0;
  for (size_t i = 1; i < r.acf.size(); ++i) acf_out += std::fabs(r.acf[i]) > r.conf;
  double ccf_peak = 0;
  int ccf_peak_lag = 0;
  for (size_t i = 0; i < r.ccf_du.size(); ++i) {
    ccf_out += std::fabs(r.ccf_du[i]) > r.conf;
    if (std::fabs(r.ccf_du[i]) > std::fabs(ccf_peak)) {
      ccf_peak = r.ccf_du[i];
      ccf_peak_lag = static_cast<int>(i) - r.max_lag;
    }
  }
  o << "\nResidual tests (95 % bound +-" << fmt("%.3g", r.conf) << ", lags up to "
    << fmt("%.3g", r.max_lag * r.lag_step_s) << " s):\n";
  o << "  auto-correlation of e: " << acf_out << " of " << r.max_lag << " lags outside the bound"
    << (acf_out > r.max_lag / 20 ? " - the residual is correlated in time (its spectrum says where)\n" : " - white\n");
  o << "  cross-correlation of e with du: " << ccf_out << " of " << r.ccf_du.size() << " lags outside the bound, peak "
    << fmt("%.3f", ccf_peak) << " at lag " << fmt("%.4g", ccf_peak_lag * r.lag_step_s) << " s"
    << (ccf_out > static_cast<int>(r.ccf_du.size()) / 20 ? " - the input still explains part of the residual\n"
                                                         : " - independent of the input\n");
  return o.str();
}

OffsetCourse offsetCourse(const double* e, size_t n) {
  const auto mean = [e](size_t from, size_t to) {
    double sum = 0.0;
    for (size_t i = from; i < to; ++i) sum += e[i];
    return to > from ? sum / static_cast<double>(to - from) : 0.0;
  };
  OffsetCourse c;
  if (n < 20) return c;
  c.head = mean(0, n / 10);
  c.tail = mean(n / 2, n);
  return c;
}

}  // namespace pamc::diagnose
