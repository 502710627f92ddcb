#include "sim/robustness.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "io/controller_settings.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "io/text.hpp"
#include "sim/lockstep.hpp"
#include "sim/robustness_cells.hpp"

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

using detail::Cells;
using detail::Variant;

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

// ---------------------------------------------------------------- variants and their runs

struct Job {
  Variant variant;
  plant::PlantConfig plant;
  const ControllerSet* ctrl = nullptr;
  std::vector<RobustnessScore> scores;  // per trajectory, filled by the run
};

// The identification amplitude of the variant's model (kIdentAmplitude: the nominal model).
double modelAmplitude(const Variant& v) {
  for (const auto& [a, value] : v.moved)
    if (a->changesModel()) return value;
  return kIdentAmplitude;
}

Job makeJob(const Variant& v, const RobustnessSettings& s, const std::map<double, ControllerSet>& sets) {
  Job j{v, s.plant, &sets.at(modelAmplitude(v)), {}};
  for (const auto& [a, value] : v.moved)
    if (!a->changesModel()) a->apply(j.plant, value);
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

// Runs the variants (s.threads workers) and stores their scores in `cells`.
void runVariants(const RobustnessSettings& s, const std::vector<TrackingCase>& cases,
                 const std::map<double, ControllerSet>& sets, const std::vector<Variant>& variants,
                 const std::string& phase, Clock::time_point t0, Cells& cells) {
  std::vector<Job> jobs;
  for (const auto& v : variants) jobs.push_back(makeJob(v, s, sets));
  runJobs(jobs, cases, s, phase, t0);
  for (auto& j : jobs) cells[j.variant.key()] = std::move(j.scores);
}

// ---------------------------------------------------------------- the settings of a set of cells

nlohmann::json axisToJson(const RobustnessAxis& a) {
  return {{"name", a.name},
          {"label", a.label},
          {"unit", a.unit},
          {"field", a.field},
          {"nominal", a.nominal},
          {"values", a.values},
          {"physics_only", a.physics_only}};
}

// The table's axis of that name (for what it sets) with the values and nominal of the record.
RobustnessAxis axisFromJson(const nlohmann::json& j, const std::vector<RobustnessAxis>& table) {
  const std::string name = j.at("name").get<std::string>();
  RobustnessAxis a = selectAxes(table, {name}).front();
  a.nominal = j.at("nominal").get<double>();
  a.values = j.at("values").get<std::vector<double>>();
  return a;
}

// The axes of the run, checked against the plant's kind.
std::vector<RobustnessAxis> axesOf(const RobustnessSettings& s) {
  const auto axes = selectAxes(s.axes.empty() ? robustnessAxes(s.plant) : s.axes, s.only_axes);
  if (axes.empty()) throw std::invalid_argument("no axis to run");
  for (const auto& a : axes)
    if (a.physics_only && s.plant.kind != plant::PlantKind::Physics)
      throw std::invalid_argument("axis '" + a.name +
                                  "' changes the physics plant; the plant is of kind model "
                                  "(--only-axes noise,model)");
  return axes;
}

// ---------------------------------------------------------------- models

// u0's record at another amplitude from the nominal plant (ident_A<tag>.csv in dir), the model fitted
// on it, and what its file records of the fit.
nlohmann::json identifyAt(const RobustnessSettings& s, const std::string& dir, double amplitude) {
  const auto log = s.log;
  const std::string tag = detail::amplitudeTag(amplitude), csv = "ident_A" + tag + ".csv";
  if (log)
    log("identifying the model on u = " + tag + " sin(0.2 pi t) + 0.2 V (" + fmt("%.0f", kIdentDuration) + " s)");
  recordOpenLoop(s.plant, identInput(amplitude), kIdentDuration, dir + csv);
  const ident::FitResult fr = identifyOnRecord(dir + csv, s.fit, log);
  if (log) log("  fitted in " + fmt("%.1f", fr.seconds) + " s, RMSE " + fmt("%.4f", fr.rmse) + " mm");
  return {{"amplitude", amplitude},
          {"model", io::modelToJson(fr.model)},
          {"fit", {{"data", csv}, {"rmse", fr.rmse}, {"seconds", fr.seconds}}}};
}

// The model of an amplitude from the document's "models", identified first when it is not there.
model::Model modelAt(const RobustnessSettings& s, const std::string& dir, double amplitude, nlohmann::json& models) {
  const std::string tag = detail::amplitudeTag(amplitude);
  if (!models.contains(tag)) models[tag] = identifyAt(s, dir, amplitude);
  return io::modelFromJson(models[tag]["model"], "cells: model " + tag);
}

// The nominal model: the document's, the file's, or the one identified on u0.
model::Model nominalModel(const RobustnessSettings& s, const std::string& dir, nlohmann::json& doc) {
  if (!doc.contains("nominal_model"))
    doc["nominal_model"] = s.model_file.empty() ? io::modelToJson(modelAt(s, dir, kIdentAmplitude, doc["models"]))
                                                : io::modelToJson(io::readModelFile(s.model_file));
  return io::modelFromJson(doc["nominal_model"], "cells: nominal_model");
}

// The controllers by model amplitude that the variants need (the nominal one under kIdentAmplitude).
std::map<double, ControllerSet> prepareControllers(const RobustnessSettings& s, const std::string& dir,
                                                   const std::vector<Variant>& variants, nlohmann::json& doc) {
  std::map<double, ControllerSet> sets;
  for (const auto& v : variants) {
    const double amplitude = modelAmplitude(v);
    if (sets.count(amplitude)) continue;
    const model::Model m =
        amplitude == kIdentAmplitude ? nominalModel(s, dir, doc) : modelAt(s, dir, amplitude, doc["models"]);
    sets.emplace(amplitude, controllerSet(s, m));
  }
  return sets;
}

// ---------------------------------------------------------------- a part of a phase

std::string makeOutDir(const std::string& out_dir) {
  io::makeDirectory(out_dir);
  return out_dir + "/";
}

// The phase's variants not yet among the cells, each once, in the table's order.
std::vector<Variant> missingVariants(const std::vector<Variant>& all, const Cells& cells) {
  std::vector<Variant> out;
  std::map<std::string, bool> seen;
  for (const auto& v : all)
    if (!cells.count(v.key()) && !seen[v.key()]) {
      seen[v.key()] = true;
      out.push_back(v);
    }
  return out;
}

// The shard's part: every count-th from the index-th (1-based).
std::vector<Variant> partOf(const std::vector<Variant>& all, const Shard& shard) {
  std::vector<Variant> out;
  for (size_t i = static_cast<size_t>(shard.index - 1); i < all.size(); i += static_cast<size_t>(shard.count))
    out.push_back(all[i]);
  return out;
}

// The pairs grid's variants, chosen from the axes' cells (all of which must be there).
std::vector<Variant> pairVariants(const RobustnessSettings& s, const std::vector<RobustnessAxis>& axes,
                                  const Cells& cells, std::string& phase) {
  if (!detail::allIn(detail::axisVariants(axes), cells))
    throw std::invalid_argument("the axes' cells are not all there: merge every part of the axes first");
  const auto results = detail::axisResults(cells, axes);
  const auto strong = detail::strongestTwo(results);
  if (!s.grid || strong.size() < 2) return {};
  const RobustnessAxis& rows =
      *std::find_if(axes.begin(), axes.end(), [&](auto& a) { return a.name == strong[0]->axis.name; });
  const RobustnessAxis& cols =
      *std::find_if(axes.begin(), axes.end(), [&](auto& a) { return a.name == strong[1]->axis.name; });
  phase = "grid " + rows.name + " x " + cols.name + ", variant";
  return detail::gridVariants(rows, cols);
}

std::string shardText(const Shard& p) { return std::to_string(p.index) + "/" + std::to_string(p.count); }

}  // namespace

Shard parseShard(const std::string& text) {
  const auto slash = text.find('/');
  Shard p;
  try {
    size_t used = 0;
    if (slash == std::string::npos) throw std::invalid_argument("");
    p.index = std::stoi(text.substr(0, slash), &used);
    if (used != slash) throw std::invalid_argument("");
    p.count = std::stoi(text.substr(slash + 1), &used);
    if (used != text.size() - slash - 1) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw std::invalid_argument("shard '" + text + "': expected I/N, e.g. 2/4");
  }
  if (p.count < 1 || p.index < 1 || p.index > p.count)
    throw std::invalid_argument("shard '" + text + "': I must be from 1 to N");
  return p;
}

nlohmann::json robustnessSettingsJson(const RobustnessSettings& s) {
  nlohmann::json axes = nlohmann::json::array();
  for (const auto& a : axesOf(s)) axes.push_back(axisToJson(a));
  return {{"plant", s.plant.toJson()},
          {"controller", io::controllerSettingsToJson(s.ctrl)},
          {"model_file", s.model_file},
          {"fit", {{"method", ident::toString(s.fit.method)}, {"seed", s.fit.ga.seed}}},
          {"axes", axes},
          {"duration_scale", s.duration_scale},
          {"score_from", s.common_window ? "common" : "own"},
          {"pairs", s.grid}};
}

RobustnessSettings robustnessSettingsFromJson(const nlohmann::json& j) {
  RobustnessSettings s;
  s.plant = plant::PlantConfig::fromJson(j.at("plant"), "cells: settings: plant");
  io::applyControllerSettings(s.ctrl, j.at("controller"));
  s.model_file = j.at("model_file").get<std::string>();
  s.fit = ident::FitSettings::forMethod(ident::fitMethodFromString(j.at("fit").at("method").get<std::string>()));
  s.fit.ga.seed = j.at("fit").at("seed").get<std::uint64_t>();
  const auto table = robustnessAxes(s.plant);
  for (const auto& a : j.at("axes")) s.axes.push_back(axisFromJson(a, table));
  s.duration_scale = j.at("duration_scale").get<double>();
  s.common_window = j.at("score_from").get<std::string>() == "common";
  s.grid = j.at("pairs").get<bool>();
  return s;
}

nlohmann::json runRobustnessCells(const RobustnessSettings& given, const nlohmann::json* axes_cells) {
  const auto t0 = Clock::now();
  RobustnessSettings s = given;
  nlohmann::json doc = {
      {"format", detail::kCellsFormat}, {"models", nlohmann::json::object()}, {"inherited_seconds", 0.0}};
  if (axes_cells) {
    s = robustnessSettingsFromJson(axes_cells->at("settings"));
    s.out_dir = given.out_dir, s.shard = given.shard, s.threads = given.threads, s.log = given.log;
    doc = *axes_cells;
    doc.erase("source");
    doc["inherited_seconds"] = axes_cells->value("inherited_seconds", 0.0) + axes_cells->value("seconds", 0.0);
  }
  const auto axes = axesOf(s);
  doc["settings"] = robustnessSettingsJson(s);
  doc["phase"] = axes_cells ? "pairs" : "axes";
  doc["shard"] = {{"index", s.shard.index}, {"count", s.shard.count}};
  doc["threads"] = s.threads;
  Cells cells = detail::cellsFromJson(doc.value("cells", nlohmann::json::object()), "cells");
  std::string phase = "one axis at a time, variant";
  const auto all = axes_cells ? pairVariants(s, axes, cells, phase) : detail::axisVariants(axes);
  const auto todo = partOf(missingVariants(all, cells), s.shard);
  if (s.shard.count > 1) phase = "part " + shardText(s.shard) + ": " + phase;
  const std::string dir = makeOutDir(s.out_dir);
  const auto sets = prepareControllers(s, dir, todo, doc);
  runVariants(s, robustnessCases(s.duration_scale), sets, todo, phase, t0, cells);
  doc["cells"] = detail::cellsToJson(cells);
  doc["seconds"] = secondsSince(t0);
  io::writeFileAtomic(dir + "cells.json", doc.dump(1) + "\n");
  return doc;
}

RobustnessReport runRobustness(const RobustnessSettings& s) {
  nlohmann::json doc = runRobustnessCells(s);
  if (s.grid) doc = runRobustnessCells(s, &doc);
  return mergeRobustness({doc}, s);
}

}  // namespace pamc::sim
