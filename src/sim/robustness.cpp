#include "sim/robustness.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "io/text.hpp"
#include "report/figures.hpp"
#include "sim/lockstep.hpp"

namespace pamc::sim {

namespace {

using io::fmt;
using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// ---------------------------------------------------------------- the axes

std::vector<double> ascendingWith(std::vector<double> v, double nominal) {
  if (std::none_of(v.begin(), v.end(), [&](double x) { return std::fabs(x - nominal) <= 1e-12 * std::fabs(nominal); }))
    v.push_back(nominal);
  std::sort(v.begin(), v.end());
  return v;
}

std::vector<double> timesNominal(double nominal, const std::vector<double>& factors) {
  std::vector<double> v;
  for (double f : factors) v.push_back(f * nominal);
  return ascendingWith(v, nominal);
}

std::vector<double> plusNominal(double nominal, const std::vector<double>& offsets) {
  std::vector<double> v;
  for (double d : offsets) v.push_back(nominal + d);
  return ascendingWith(v, nominal);
}

void setFlow(plant::PlantConfig& p, double v) { p.physics.regulator.conductance_dm3_per_s_bar = v; }
void setMass(plant::PlantConfig& p, double v) { p.physics.payload.mass_kg = v; }
void setSupply(plant::PlantConfig& p, double v) { p.physics.regulator.supply_bar = v; }
// The sensor noise of either kind: the physics plant's, and the fields the model kind reads.
void setNoise(plant::PlantConfig& p, double v) {
  p.physics.noise_std_mm = v;
  p.noise_std_mm = v;
  p.sensor_noise = v > 0.0;
}

std::string axisNames(const std::vector<RobustnessAxis>& axes) {
  std::string names;
  for (const auto& a : axes) names += (names.empty() ? "" : ", ") + a.name;
  return names;
}

}  // namespace

std::vector<RobustnessAxis> robustnessAxes(const plant::PlantConfig& nominal) {
  const auto& ph = nominal.physics;
  const double flow = ph.regulator.conductance_dm3_per_s_bar, mass = ph.payload.mass_kg;
  const double supply = ph.regulator.supply_bar, noise = nominal.noise_std_mm;
  return {
      {"flow", "valve flow (sonic conductance C of valve + tube)", "dm3/(s bar)", "regulator.conductance_dm3_per_s_bar",
       flow, timesNominal(flow, {0.4, 0.7, 1.3, 1.6}), true, setFlow},
      {"mass", "payload mass", "kg", "payload.mass_kg", mass, timesNominal(mass, {0.5, 0.75, 1.5, 2.0}), true, setMass},
      {"supply", "supply pressure (the top of the command asks for 8 bar)", "bar", "regulator.supply_bar", supply,
       plusNominal(supply, {-3.0, -2.0, -1.0, 1.0}), true, setSupply},
      {"noise", "sensor noise (standard deviation)", "mm", "sensor.noise_std_mm", noise,
       ascendingWith({0.001, 0.01, 0.02, 0.05}, noise), false, setNoise},
      {"model", "amplitude A of the identification input u = A sin(0.2 pi t) + 0.2 V", "V", "", kIdentAmplitude,
       ascendingWith({1.0, 1.4, 2.0, 3.5}, kIdentAmplitude), false, nullptr},
  };
}

std::vector<RobustnessAxis> selectAxes(const std::vector<RobustnessAxis>& all, const std::vector<std::string>& names) {
  for (const auto& n : names)
    if (std::none_of(all.begin(), all.end(), [&](const RobustnessAxis& a) { return a.name == n; }))
      throw std::invalid_argument("unknown axis '" + n + "' (known: " + axisNames(all) + ")");
  std::vector<RobustnessAxis> out;
  for (const auto& a : all)
    if (names.empty() || std::find(names.begin(), names.end(), a.name) != names.end()) out.push_back(a);
  return out;
}

std::vector<TrackingCase> robustnessCases(double duration_scale) {
  std::vector<TrackingCase> cases = table2Cases(SineStart::Centre);
  cases.push_back(discontinuousCases().front());  // the square wave
  if (cases.back().tag != "square") throw std::logic_error("robustnessCases: the first discontinuous case changed");
  for (auto& c : cases) c.run.duration_s *= duration_scale;
  return cases;
}

namespace {

// ---------------------------------------------------------------- controllers and models

// In the order of RobustnessScore's fields.
const control::Kind kKinds[] = {control::Kind::PI, control::Kind::PidEso, control::Kind::PiAmc, control::Kind::Mbc};

// A controller configuration with the inverse its runs start from; one per model.
struct ControllerSet {
  control::ControllerConfig cc;
  control::InverseStatic inv;
};

ControllerSet controllerSet(const RobustnessSettings& s, const model::Model& m) {
  ControllerSet c;
  c.cc = controllerFor(s.ctrl, m, s.plant);
  control::validate(c.cc);  // throws here, not in a worker
  c.inv.build(m, c.cc.u_min, c.cc.u_max, s.plant.Ts);
  return c;
}

std::string amplitudeTag(double a) { return fmt("%.2f", a); }

// u0's record at another amplitude from the nominal plant, and the model fitted on it (files in dir).
model::Model identifyAt(const RobustnessSettings& s, const std::string& dir, double amplitude) {
  const auto log = s.log;
  const std::string tag = amplitudeTag(amplitude);
  if (log) log("identifying the model on u = " + tag + " sin(0.2 pi t) + 0.2 V (" + fmt("%.0f", kIdentDuration) + " s)");
  recordOpenLoop(s.plant, identInput(amplitude), kIdentDuration, dir + "ident_A" + tag + ".csv");
  const ident::FitResult fr = identifyOnRecord(dir + "ident_A" + tag + ".csv", s.fit, log);
  io::writeModelFile(dir + "model_A" + tag + ".json", fr.model,
                     {{"data", "ident_A" + tag + ".csv"}, {"rmse", fr.rmse}, {"seconds", fr.seconds}});
  if (log) log("  fitted in " + fmt("%.1f", fr.seconds) + " s, RMSE " + fmt("%.4f", fr.rmse) + " mm");
  return fr.model;
}

// The controllers by model amplitude: the nominal one (identified or read) and, when the model axis is
// among the axes, one per amplitude it lists.
std::map<double, ControllerSet> prepareControllers(const RobustnessSettings& s, const std::string& dir,
                                                   const std::vector<RobustnessAxis>& axes) {
  std::map<double, ControllerSet> sets;
  const model::Model nominal =
      s.model_file.empty() ? identifyAt(s, dir, kIdentAmplitude) : io::readModelFile(s.model_file);
  sets.emplace(kIdentAmplitude, controllerSet(s, nominal));
  for (const auto& a : axes)
    if (a.changesModel())
      for (double v : a.values)
        if (!sets.count(v)) sets.emplace(v, controllerSet(s, identifyAt(s, dir, v)));
  return sets;
}

// ---------------------------------------------------------------- variants and their runs

// A plant (and model) variant: the axes it moves away from the nominal, in the table's order.
struct Variant {
  std::vector<std::pair<const RobustnessAxis*, double>> moved;
  std::string key() const {
    std::string k;
    for (const auto& [a, v] : moved) k += a->name + "=" + fmt("%.9g", v) + ";";
    return k;
  }
  std::string label() const {
    std::string l;
    for (const auto& [a, v] : moved) l += (l.empty() ? "" : ", ") + a->name + " " + fmt("%g", v) + " " + a->unit;
    return l.empty() ? "nominal" : l;
  }
};

// Adds (axis, value) to a variant unless the value is the axis's nominal.
Variant moveTo(Variant v, const RobustnessAxis& a, double value) {
  if (value != a.nominal) v.moved.emplace_back(&a, value);
  return v;
}

struct Job {
  Variant variant;
  plant::PlantConfig plant;
  const ControllerSet* ctrl = nullptr;
  std::vector<RobustnessScore> scores;  // per trajectory, filled by the run
};

Job makeJob(const Variant& v, const RobustnessSettings& s, const std::map<double, ControllerSet>& sets) {
  Job j{v, s.plant, &sets.at(kIdentAmplitude), {}};
  for (const auto& [a, value] : v.moved) {
    if (a->changesModel()) j.ctrl = &sets.at(value);
    else a->apply(j.plant, value);
  }
  return j;
}

// The four controllers on one trajectory. A run that starts away from home is scored from its first
// reach (Table 2's rule); with a common window all four from the latest of their first reaches, so that
// the ratios compare the same stretch of time (a controller that reaches early is not scored on a
// transient the others are not scored on).
RobustnessScore scoreCase(const Job& job, const TrackingCase& c, bool common_window) {
  std::vector<Record> recs;
  double latest = 0.0;
  for (auto kind : kKinds) {
    recs.push_back(runController(kind, job.ctrl->cc, job.ctrl->inv, job.plant, c.run));
    latest = std::max(latest, scoredFrom(recs.back(), c.run));
  }
  auto rmse = [&](size_t i) { return tracking(recs[i], common_window ? latest : scoredFrom(recs[i], c.run)).rmse; };
  return {c.tag, rmse(0), rmse(1), rmse(2), rmse(3), common_window ? latest : NAN};
}

// Every trajectory with every controller; fresh plants, controllers and records per run.
void runJob(Job& job, const std::vector<TrackingCase>& cases, bool common_window) {
  job.scores.clear();
  for (const auto& c : cases) job.scores.push_back(scoreCase(job, c, common_window));
}

// What the workers share: the job list (each job touched by one worker only), the next index, the
// progress count and log under a mutex, the first exception.
struct WorkQueue {
  WorkQueue(std::vector<Job>& j, const std::vector<TrackingCase>& c, const RobustnessSettings& st, std::string ph,
            Clock::time_point start)
      : jobs(j), cases(c), s(st), phase(std::move(ph)), t0(start) {}
  std::vector<Job>& jobs;
  const std::vector<TrackingCase>& cases;
  const RobustnessSettings& s;
  std::string phase;
  Clock::time_point t0;
  std::atomic<size_t> next{0};
  std::mutex mutex;
  size_t done = 0;
  std::exception_ptr error;
};

void reportDone(WorkQueue& q, const Job& job) {
  std::lock_guard<std::mutex> lock(q.mutex);
  ++q.done;
  if (q.s.log)
    q.s.log(q.phase + " " + std::to_string(q.done) + "/" + std::to_string(q.jobs.size()) + ": " + job.variant.label() +
            " (" + fmt("%.1f", secondsSince(q.t0)) + " s)");
}

void workerLoop(WorkQueue& q) {
  for (size_t i = q.next++; i < q.jobs.size(); i = q.next++) {
    try {
      runJob(q.jobs[i], q.cases, q.s.common_window);
      reportDone(q, q.jobs[i]);
    } catch (...) {
      std::lock_guard<std::mutex> lock(q.mutex);
      if (!q.error) q.error = std::current_exception();
    }
  }
}

void runJobs(std::vector<Job>& jobs, const std::vector<TrackingCase>& cases, const RobustnessSettings& s,
             const std::string& phase, Clock::time_point t0) {
  WorkQueue q(jobs, cases, s, phase, t0);
  const int n = std::max(1, std::min<int>(s.threads, static_cast<int>(jobs.size())));
  std::vector<std::thread> workers;
  for (int i = 1; i < n; ++i) workers.emplace_back(workerLoop, std::ref(q));
  workerLoop(q);
  for (auto& w : workers) w.join();
  if (q.error) std::rethrow_exception(q.error);
}

// Scores by variant key: every variant runs once however many sweeps list it.
using ScoreCache = std::map<std::string, std::vector<RobustnessScore>>;

struct RunContext {
  const RobustnessSettings& s;
  const std::vector<TrackingCase>& cases;
  const std::map<double, ControllerSet>& sets;
  Clock::time_point t0;
  ScoreCache cache;
  int variants = 0;
};

// Runs the variants not yet in the cache (two workers) and stores their scores.
void runVariants(RunContext& ctx, const std::vector<Variant>& variants, const std::string& phase) {
  std::vector<Job> jobs;
  std::map<std::string, bool> queued;
  for (const auto& v : variants)
    if (!ctx.cache.count(v.key()) && !queued[v.key()]) {
      queued[v.key()] = true;
      jobs.push_back(makeJob(v, ctx.s, ctx.sets));
    }
  runJobs(jobs, ctx.cases, ctx.s, phase, ctx.t0);
  for (auto& j : jobs) ctx.cache[j.variant.key()] = std::move(j.scores);
  ctx.variants += static_cast<int>(jobs.size());
}

// ---------------------------------------------------------------- one axis at a time, the grid

double meanAmcOverPi(const std::vector<RobustnessScore>& scores) {
  double sum = 0.0;
  for (const auto& sc : scores) sum += sc.amcOverPi();
  return scores.empty() ? NAN : sum / static_cast<double>(scores.size());
}

std::vector<AxisResult> sweepAxes(RunContext& ctx, const std::vector<RobustnessAxis>& axes) {
  std::vector<Variant> variants;
  for (const auto& a : axes)
    for (double v : a.values) variants.push_back(moveTo({}, a, v));
  runVariants(ctx, variants, "one axis at a time, variant");
  std::vector<AxisResult> out;
  for (const auto& a : axes) {
    AxisResult r{a, {}, {}, 0.0};
    for (double v : a.values) {
      r.scores.push_back(ctx.cache.at(moveTo({}, a, v).key()));
      r.mean_amc_over_pi.push_back(meanAmcOverPi(r.scores.back()));
    }
    const auto [lo, hi] = std::minmax_element(r.mean_amc_over_pi.begin(), r.mean_amc_over_pi.end());
    r.spread = *hi - *lo;
    out.push_back(std::move(r));
  }
  return out;
}

// The two axes along which the mean AMC/PI ratio spreads most, strongest first.
std::vector<const AxisResult*> strongestTwo(const std::vector<AxisResult>& axes) {
  std::vector<const AxisResult*> order;
  for (const auto& a : axes) order.push_back(&a);
  std::stable_sort(order.begin(), order.end(), [](const AxisResult* x, const AxisResult* y) { return x->spread > y->spread; });
  if (order.size() > 2) order.resize(2);
  return order;
}

GridResult sweepGrid(RunContext& ctx, const RobustnessAxis& rows, const RobustnessAxis& cols) {
  std::vector<Variant> variants;
  for (double r : rows.values)
    for (double c : cols.values) variants.push_back(moveTo(moveTo({}, rows, r), cols, c));
  runVariants(ctx, variants, "grid " + rows.name + " x " + cols.name + ", variant");
  GridResult g{rows.name, cols.name, rows.values, cols.values, {}};
  for (double r : rows.values) {
    g.scores.emplace_back();
    for (double c : cols.values) g.scores.back().push_back(ctx.cache.at(moveTo(moveTo({}, rows, r), cols, c).key()));
  }
  return g;
}

// ---------------------------------------------------------------- files

std::string scoreCells(const RobustnessScore& sc) {
  return sc.trajectory + "," + fmt("%.6g", sc.pi) + "," + fmt("%.6g", sc.eso) + "," + fmt("%.6g", sc.amc) + "," +
         fmt("%.6g", sc.amcOverPi()) + "," + fmt("%.6g", sc.esoOverPi()) + "," + fmt("%.6g", sc.mbc) + "," +
         fmt("%.6g", sc.mbcOverPi());
}

void writeAxisCsv(const std::string& dir, const AxisResult& r) {
  std::string out = "value,trajectory,pi_rmse,eso_rmse,amc_rmse,amc_over_pi,eso_over_pi,mbc_rmse,mbc_over_pi\n";
  for (size_t i = 0; i < r.axis.values.size(); ++i)
    for (const auto& sc : r.scores[i]) out += fmt("%.9g", r.axis.values[i]) + "," + scoreCells(sc) + "\n";
  io::writeFileAtomic(dir + "axis_" + r.axis.name + ".csv", out);
}

void writeGridCsv(const std::string& dir, const GridResult& g) {
  std::string out = g.row_axis + "," + g.col_axis + ",trajectory,pi_rmse,eso_rmse,amc_rmse,amc_over_pi,eso_over_pi,mbc_rmse,mbc_over_pi\n";
  for (size_t r = 0; r < g.row_values.size(); ++r)
    for (size_t c = 0; c < g.col_values.size(); ++c)
      for (const auto& sc : g.scores[r][c])
        out += fmt("%.9g", g.row_values[r]) + "," + fmt("%.9g", g.col_values[c]) + "," + scoreCells(sc) + "\n";
  io::writeFileAtomic(dir + "grid.csv", out);
}

// ---------------------------------------------------------------- figures

using Ratio = double (RobustnessScore::*)() const;

std::vector<std::string> valueLabels(const RobustnessAxis& a) {
  std::vector<std::string> l;
  for (double v : a.values) l.push_back(fmt("%g", v) + (v == a.nominal ? " (nominal)" : ""));
  return l;
}

// Rows = the axis's values, columns = the trajectories.
report::Heatmap axisMap(const AxisResult& r, Ratio ratio, const std::string& what) {
  report::Heatmap m;
  m.title = what;
  m.xlabel = "trajectory";
  m.ylabel = r.axis.name + " [" + r.axis.unit + "]";
  m.yticks = valueLabels(r.axis);
  for (const auto& sc : r.scores.front()) m.xticks.push_back(sc.trajectory);
  for (const auto& row : r.scores) {
    m.z.emplace_back();
    for (const auto& sc : row) m.z.back().push_back((sc.*ratio)());
  }
  return m;
}

// One trajectory of the grid (index t), or the mean over the trajectories (t = npos).
report::Heatmap gridMap(const GridResult& g, const RobustnessAxis& rows, const RobustnessAxis& cols, Ratio ratio,
                        size_t t) {
  report::Heatmap m;
  m.title = t == std::string::npos ? "mean over the trajectories" : g.scores[0][0][t].trajectory;
  m.xlabel = cols.name + " [" + cols.unit + "]";
  m.ylabel = rows.name + " [" + rows.unit + "]";
  m.xticks = valueLabels(cols);
  m.yticks = valueLabels(rows);
  for (const auto& row : g.scores) {
    m.z.emplace_back();
    for (const auto& cell : row) {
      double sum = 0.0;
      for (const auto& sc : cell) sum += (sc.*ratio)();
      m.z.back().push_back(t == std::string::npos ? sum / static_cast<double>(cell.size()) : (cell[t].*ratio)());
    }
  }
  return m;
}

const char* kColourKey = "RMSE ratio (blue < 1: beats PI, red > 1: worse than PI)";

void renderAxis(const std::string& dir, const AxisResult& r, std::string& error) {
  const std::vector<report::Heatmap> maps = {axisMap(r, &RobustnessScore::amcOverPi, "PI+AMC / PI"),
                                             axisMap(r, &RobustnessScore::esoOverPi, "PID+ESO / PI")};
  const std::string title = "RMSE against PI over " + r.axis.label + " (nominal " + fmt("%g", r.axis.nominal) + " " +
                            r.axis.unit + ")" + (r.axis.changesModel() ? "; the plant is nominal" : "; the model is nominal");
  if (!report::renderHeatmaps(dir + "axis_" + r.axis.name + ".png", title, maps, 1.0, kColourKey, error))
    throw std::runtime_error(error);
}

void renderGrid(const std::string& dir, const GridResult& g, const RobustnessAxis& rows, const RobustnessAxis& cols,
                Ratio ratio, const std::string& name, const std::string& what) {
  std::vector<report::Heatmap> maps;
  for (size_t t = 0; t < g.scores[0][0].size(); ++t) maps.push_back(gridMap(g, rows, cols, ratio, t));
  maps.push_back(gridMap(g, rows, cols, ratio, std::string::npos));
  std::string error;
  if (!report::renderHeatmaps(dir + name + ".png", what + " RMSE ratio over " + rows.name + " x " + cols.name, maps, 1.0,
                              kColourKey, error, 3))
    throw std::runtime_error(error);
}

// ---------------------------------------------------------------- summary

nlohmann::json scoresJson(const std::vector<RobustnessScore>& scores) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& sc : scores)
    j[sc.trajectory] = {{"pi_rmse", sc.pi}, {"eso_rmse", sc.eso}, {"amc_rmse", sc.amc},
                        {"amc_over_pi", sc.amcOverPi()}, {"eso_over_pi", sc.esoOverPi()},
                        {"mbc_rmse", sc.mbc}, {"mbc_over_pi", sc.mbcOverPi()},
                        {"scored_from_s", sc.scored_from_s}};  // null: each run from its own first reach
  return j;
}

nlohmann::json axisJson(const AxisResult& r) {
  nlohmann::json rows = nlohmann::json::array();
  for (size_t i = 0; i < r.axis.values.size(); ++i)
    rows.push_back({{"value", r.axis.values[i]}, {"mean_amc_over_pi", r.mean_amc_over_pi[i]},
                    {"trajectories", scoresJson(r.scores[i])}});
  return {{"label", r.axis.label}, {"unit", r.axis.unit}, {"field", r.axis.field}, {"nominal", r.axis.nominal},
          {"values", r.axis.values}, {"spread_of_mean_amc_over_pi", r.spread}, {"rows", rows}};
}

nlohmann::json gridJson(const GridResult& g) {
  nlohmann::json cells = nlohmann::json::array();
  for (size_t r = 0; r < g.row_values.size(); ++r)
    for (size_t c = 0; c < g.col_values.size(); ++c)
      cells.push_back({{g.row_axis, g.row_values[r]}, {g.col_axis, g.col_values[c]}, {"trajectories", scoresJson(g.scores[r][c])}});
  return {{"rows", g.row_axis}, {"columns", g.col_axis}, {"row_values", g.row_values}, {"column_values", g.col_values},
          {"cells", cells}};
}

// "triangle_0.05Hz" -> "tri.05Hz", "sine_0.1Hz" -> "sin.1Hz": a column head of the text tables.
std::string shortTag(std::string tag) {
  for (const char* long_form : {"triangle_0", "sine_0"}) {
    const std::string lf = long_form;
    if (tag.compare(0, lf.size(), lf) == 0) tag = lf.substr(0, 3) + tag.substr(lf.size());
  }
  return tag;
}

std::string ratioRow(const std::vector<RobustnessScore>& scores) {
  std::string amc, eso;
  for (const auto& sc : scores) {
    amc += fmt("%9.3f", sc.amcOverPi());
    eso += fmt("%9.3f", sc.esoOverPi());
  }
  return amc + " |" + eso;
}

std::string axisText(const AxisResult& r) {
  std::ostringstream t;
  t << "Axis " << r.axis.name << ": " << r.axis.label << " [" << r.axis.unit << "], nominal " << fmt("%g", r.axis.nominal)
    << "; spread of the mean AMC/PI " << fmt("%.3f", r.spread) << "\n";
  std::string head;
  for (const auto& sc : r.scores.front()) {
    char b[16];
    std::snprintf(b, sizeof b, "%9s", shortTag(sc.trajectory).c_str());
    head += b;
  }
  t << "  AMC/PI, ESO/PI and PI's RMSE [mm] by trajectory\n  value        " << head << " |" << head << " |" << head << "\n";
  for (size_t i = 0; i < r.axis.values.size(); ++i) {
    std::string pi;
    for (const auto& sc : r.scores[i]) pi += fmt("%9.3f", sc.pi);
    t << "  " << fmt("%-10g", r.axis.values[i]) << (r.axis.values[i] == r.axis.nominal ? "*" : " ") << "  "
      << ratioRow(r.scores[i]) << " |" << pi << "\n";
  }
  return t.str() + "\n";
}

std::string gridText(const GridResult& g) {
  std::ostringstream t;
  t << "Grid " << g.row_axis << " (rows) x " << g.col_axis << " (columns): AMC/PI RMSE ratio, mean over the trajectories\n";
  t << std::string(12, ' ');
  for (double c : g.col_values) t << fmt("%10g", c);
  t << "\n";
  for (size_t r = 0; r < g.row_values.size(); ++r) {
    t << "  " << fmt("%10g", g.row_values[r]);
    for (const auto& cell : g.scores[r]) t << fmt("%10.3f", meanAmcOverPi(cell));
    t << "\n";
  }
  return t.str() + "\n";
}

// ---------------------------------------------------------------- the command's steps

std::string makeOutDir(const std::string& out_dir) {
  io::makeDirectory(out_dir);
  return out_dir + "/";
}

// The axes of the run, checked against the plant's kind.
std::vector<RobustnessAxis> axesOf(const RobustnessSettings& s) {
  const auto axes = selectAxes(s.axes.empty() ? robustnessAxes(s.plant) : s.axes, s.only_axes);
  if (axes.empty()) throw std::invalid_argument("no axis to run");
  for (const auto& a : axes)
    if (a.physics_only && s.plant.kind != plant::PlantKind::Physics)
      throw std::invalid_argument("axis '" + a.name + "' changes the physics plant; the plant is of kind model "
                                  "(--only-axes noise,model)");
  return axes;
}

void renderFigures(const std::string& dir, const RobustnessReport& rep, const std::vector<RobustnessAxis>& axes,
                   const RobustnessSettings& s) {
  if (!s.figures) return;
  if (!report::haveGnuplot()) {
    if (s.log) s.log("warning: gnuplot not found (apt-get install gnuplot-nox); heat maps skipped, CSVs written");
    return;
  }
  try {
    std::string error;
    for (const auto& r : rep.axes) renderAxis(dir, r, error);
    if (rep.grid.scores.empty()) return;
    const RobustnessAxis rows = selectAxes(axes, {rep.grid.row_axis}).front();
    const RobustnessAxis cols = selectAxes(axes, {rep.grid.col_axis}).front();
    renderGrid(dir, rep.grid, rows, cols, &RobustnessScore::amcOverPi, "grid_amc_over_pi", "PI+AMC / PI");
    renderGrid(dir, rep.grid, rows, cols, &RobustnessScore::esoOverPi, "grid_eso_over_pi", "PID+ESO / PI");
  } catch (const std::runtime_error& e) {
    if (s.log) s.log(std::string("warning: ") + e.what());
  }
}

void writeSummary(const std::string& dir, RobustnessReport& rep, const RobustnessSettings& s) {
  std::ostringstream t;
  t << "RMSE of PID+ESO and PI+AMC against PI (ratio < 1: better than PI) on the triangle, the two sines and the\n"
       "square wave, over plant changes the controllers were not tuned for ('*': nominal).\n"
    << (s.common_window ? "The sines (started away from home) are scored over one window for all four controllers, from the\n"
                          "latest of their first reaches.\n\n"
                        : "Every run is scored from its own first reach (Table 2's rule).\n\n");
  nlohmann::json axes = nlohmann::json::object();
  for (const auto& r : rep.axes) {
    t << axisText(r);
    axes[r.axis.name] = axisJson(r);
  }
  t << "Strongest axes (largest spread of the mean AMC/PI ratio):";
  for (const auto& n : rep.strongest) t << " " << n;
  t << "\n\n";
  if (!rep.grid.scores.empty()) t << gridText(rep.grid);
  t << rep.variants << " variants x " << rep.axes.front().scores.front().size() << " trajectories x 4 controllers in "
    << fmt("%.1f", rep.seconds) << " s on " << s.threads << " worker threads\n";
  rep.text = t.str();
  rep.json = {{"axes", axes}, {"strongest", rep.strongest}, {"variants", rep.variants}, {"seconds", rep.seconds},
              {"threads", s.threads}, {"score_from", s.common_window ? "common" : "own"}, {"plant", s.plant.toJson()}};
  if (!rep.grid.scores.empty()) rep.json["grid"] = gridJson(rep.grid);
  io::writeFileAtomic(dir + "summary.txt", rep.text);
  io::writeFileAtomic(dir + "summary.json", rep.json.dump(2) + "\n");
}

}  // namespace

RobustnessReport runRobustness(const RobustnessSettings& s) {
  const auto t0 = Clock::now();
  const std::vector<RobustnessAxis> axes = axesOf(s);
  const std::string dir = makeOutDir(s.out_dir);
  const auto cases = robustnessCases(s.duration_scale);
  const auto sets = prepareControllers(s, dir, axes);
  RunContext ctx{s, cases, sets, t0, {}, 0};  // progress times from the start, identification included
  RobustnessReport rep;
  rep.axes = sweepAxes(ctx, axes);
  for (const auto& r : rep.axes) writeAxisCsv(dir, r);
  const auto strong = strongestTwo(rep.axes);
  for (const auto* a : strong) rep.strongest.push_back(a->axis.name);
  if (s.grid && strong.size() == 2) {
    rep.grid = sweepGrid(ctx, strong[0]->axis, strong[1]->axis);
    writeGridCsv(dir, rep.grid);
  }
  rep.variants = ctx.variants;
  rep.seconds = secondsSince(t0);
  renderFigures(dir, rep, axes, s);
  writeSummary(dir, rep, s);
  return rep;
}

}  // namespace pamc::sim
