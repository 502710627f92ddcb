#include "diagnose/compare.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "report/figures.hpp"

namespace pamc::diagnose {

RangeShare rangeShare(const model::OperatingRange& r, const io::Measurement& d) {
  RangeShare s;
  s.known = r.known;
  if (!r.known || d.size() == 0) return s;
  size_t in = 0, out = 0, rate = 0, any = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    const bool a = !r.input.contains(d.u[i]);
    const bool b = !r.output.contains(d.y[i]);
    const bool c = i > 0 && !r.rate.contains((d.u[i] - d.u[i - 1]) / d.Ts);
    in += a;
    out += b;
    rate += c;
    any += a || b || c;
  }
  const double n = static_cast<double>(d.size());
  s.input = in / n;
  s.output = out / n;
  s.rate = rate / n;
  s.any = any / n;
  return s;
}

std::string describeRangeShare(const RangeShare& s, const model::OperatingRange& r) {
  if (!s.known) return "the model file records no range it was identified on (an older file): nothing to check against";
  char b[400];
  std::snprintf(
      b, sizeof b,
      "outside the range the model was identified on: %.1f %% of the samples (input %.1f %% outside [%g, %g], "
      "output %.1f %% outside [%g, %g], input rate %.1f %% outside [%g, %g]/s)",
      100 * s.any, 100 * s.input, r.input.lo, r.input.hi, 100 * s.output, r.output.lo, r.output.hi, 100 * s.rate,
      r.rate.lo, r.rate.hi);
  return b;
}

namespace {
// The input range the model was identified on, or the record's where it records none (empty: neither).
model::Interval inputsOf(const model::Model& m, const io::Measurement& d) {
  if (m.range().known) return m.range().input;
  if (d.u.empty()) return {0.0, 0.0};
  const auto [lo, hi] = std::minmax_element(d.u.begin(), d.u.end());
  return {*lo, *hi};
}
}  // namespace

Comparison compare(const model::Model& m, const io::Measurement& d) {
  if (m.needsLoad() && !d.has("load"))
    throw std::invalid_argument(d.source + ": the model has the 'load' effect but the data has no 'load' column");
  Comparison c;
  const auto* load = d.column("load");
  c.y_model.resize(d.size());
  m.simulate(d.u.data(), load ? load->data() : nullptr, d.size(), d.Ts, c.y_model.data());
  c.report = analyze(d, c.y_model);
  c.outside = rangeShare(m.range(), d);
  c.rests = ident::recordRests(d);
  const model::Interval u = inputsOf(m, d);
  c.fold = model::inverseFold(m, u.lo, u.hi);
  c.rest = model::heldRest(m, d.Ts, u.lo, u.hi);
  std::vector<double> e(d.size());
  for (size_t i = 0; i < d.size(); ++i) e[i] = d.y[i] - c.y_model[i];
  c.spectrum = residualSpectrum(e, d.u, d.Ts, c.report.noise_floor);
  return c;
}

namespace {
nlohmann::json rangeJson(const RangeShare& s) {
  if (!s.known) return nullptr;
  return {{"any", s.any}, {"input", s.input}, {"output", s.output}, {"input_rate", s.rate}};
}
nlohmann::json restJson(const ident::ExtremeRest& r) {
  return {{"share", r.share}, {"input_moved", r.input_moved}, {"on_stop", r.on_stop}};
}
}  // namespace

nlohmann::json toJson(const Comparison& c) {
  const auto& r = c.report;
  nlohmann::json bins = nlohmann::json::array();
  for (const auto& b : r.bins)
    bins.push_back({{"group", b.group}, {"label", b.label}, {"n", b.n}, {"rmse", b.rmse}, {"mean", b.mean}});
  return {
      {"samples", r.n},
      {"rmse", r.rmse},
      {"max_abs", r.max_abs},
      {"fit_pct", r.fit_pct},
      {"mean", r.mean},
      {"noise_floor", r.noise_floor},
      {"breakdown", bins},
      {"indicators", r.ind},
      {"acf", r.acf},
      {"ccf_du", r.ccf_du},
      {"conf", r.conf},
      {"lag_step_s", r.lag_step_s},
      {"spectrum", toJson(c.spectrum)},
      {"outside_range", rangeJson(c.outside)},
      {"end_stops", {{"low", restJson(c.rests.low)}, {"high", restJson(c.rests.high)}}},
      {"inverse",
       {{"folds", c.fold.folds}, {"least_slope", c.fold.least}, {"at_input", c.fold.at_input}, {"gain", c.fold.gain}}},
      {"held_rest",
       {{"rests", c.rest.rests}, {"swing", c.rest.swing}, {"at_input", c.rest.at_command}, {"span", c.rest.span}}}};
}

void writeCompareReport(const Comparison& c, const io::Measurement& d, const std::string& dir,
                        std::vector<std::string>* warnings) {
  io::makeDirectory(dir, "report directory");
  const std::string p = dir + "/";
  std::vector<double> e(d.size());
  for (size_t i = 0; i < d.size(); ++i) e[i] = d.y[i] - c.y_model[i];
  io::writeCsvAtomic(p + "compare.csv", {"t", "u", "y", "y_model", "residual"}, {&d.t, &d.u, &d.y, &c.y_model, &e});
  const auto& r = c.report;
  std::vector<double> lag, acf, up, dn, clag, ccf, cup, cdn;
  for (size_t i = 0; i < r.acf.size(); ++i) {
    lag.push_back(static_cast<double>(i) * r.lag_step_s);
    acf.push_back(r.acf[i]);
    up.push_back(r.conf);
    dn.push_back(-r.conf);
  }
  for (size_t i = 0; i < r.ccf_du.size(); ++i) {
    clag.push_back((static_cast<double>(i) - r.max_lag) * r.lag_step_s);
    ccf.push_back(r.ccf_du[i]);
    cup.push_back(r.conf);
    cdn.push_back(-r.conf);
  }
  io::writeCsvAtomic(p + "acf.csv", {"lag_s", "acf", "upper", "lower"}, {&lag, &acf, &up, &dn});
  io::writeCsvAtomic(p + "ccf.csv", {"lag_s", "ccf", "upper", "lower"}, {&clag, &ccf, &cup, &cdn});
  {
    std::string t = "group,label,n,rmse,mean,where\n";
    for (const auto& b : r.bins)
      t += b.group + "," + b.label + "," + std::to_string(b.n) + "," + std::to_string(b.rmse) + "," +
           std::to_string(b.mean) + "," + b.group + ": " + b.label + "\n";
    io::writeFileAtomic(p + "breakdown.csv", t);
  }
  io::writeFileAtomic(p + "compare.json", toJson(c).dump(2) + "\n");
  writeSpectrumReport(c.spectrum, p, "The residual in frequency: " + d.source, warnings);
  if (!report::haveGnuplot()) {
    if (warnings) warnings->push_back("gnuplot not found (apt-get install gnuplot-nox); figures skipped");
    return;
  }
  std::string err;
  const std::string cc = p + "compare.csv";
  char title[200];
  std::snprintf(title, sizeof title, "%s: RMSE %.4g, max %.4g, fit %.1f %%", d.source.c_str(), r.rmse, r.max_abs,
                r.fit_pct);
  if (!report::renderFigure(
          p + "compare.png", title,
          {{"measured and model over time", "t [s]", "y", {{cc, "t", "y", "measured"}, {cc, "t", "y_model", "model"}}},
           {"loops: y against u", "u", "y", {{cc, "u", "y", "measured"}, {cc, "u", "y_model", "model"}}},
           {"residual over time", "t [s]", "y - model", {{cc, "t", "residual", "residual"}}}},
          err))
    if (warnings) warnings->push_back(err);
  if (!report::renderBars(p + "breakdown.png", "Where the error is: RMSE of y - model by group", p + "breakdown.csv", 6,
                          4, "RMSE", err))
    if (warnings) warnings->push_back(err);
  if (!report::renderFigure(p + "residual_tests.png", "Residual tests with 95 % bounds",
                            {{"auto-correlation of the residual",
                              "lag [s]",
                              "acf",
                              {{p + "acf.csv", "lag_s", "acf", "acf"},
                               {p + "acf.csv", "lag_s", "upper", "95 % bound", "lines dt 2 lc 'black'"},
                               {p + "acf.csv", "lag_s", "lower", "", "lines dt 2 lc 'black'"}}},
                             {"cross-correlation of the residual with the input increments",
                              "lag [s]",
                              "ccf",
                              {{p + "ccf.csv", "lag_s", "ccf", "ccf"},
                               {p + "ccf.csv", "lag_s", "upper", "95 % bound", "lines dt 2 lc 'black'"},
                               {p + "ccf.csv", "lag_s", "lower", "", "lines dt 2 lc 'black'"}}}},
                            err))
    if (warnings) warnings->push_back(err);
}

}  // namespace pamc::diagnose
