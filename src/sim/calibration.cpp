#include "sim/calibration.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <thread>

#include "io/measurement.hpp"
#include "io/text.hpp"

namespace pamc::sim {

namespace {

using io::fmt;

const physics::PhysicsConfig& physicsDefaults() {
  static const physics::PhysicsConfig d = physics::PhysicsConfig::defaults();
  return d;
}

void setHysteresisScale(plant::PlantConfig& p, double s) {
  p.physics.muscle.hysteresis_N = physicsDefaults().muscle.hysteresis_N * s;
  p.physics.muscle.hysteresis_N_per_bar = physicsDefaults().muscle.hysteresis_N_per_bar * s;
}
void setTravel(plant::PlantConfig& p, double v) { p.physics.muscle.hysteresis_travel_mm = v; }
void setConductance(plant::PlantConfig& p, double v) { p.physics.regulator.conductance_dm3_per_s_bar = v; }
void setMass(plant::PlantConfig& p, double v) { p.physics.payload.mass_kg = v; }

std::vector<CalibrationAxis> buildAxes() {
  const auto& d = physicsDefaults();
  return {
      {"hysteresis_scale",
       "-",
       "braid friction level: muscle.hysteresis_N and hysteresis_N_per_bar times this",
       {0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.5},
       1.0,
       setHysteresisScale},
      {"hysteresis_travel_mm",
       "mm",
       "pre-sliding travel of the braid friction (muscle.hysteresis_travel_mm)",
       {0.1, 0.3, 1.0, 3.0, 6.0},
       d.muscle.hysteresis_travel_mm,
       setTravel},
      {"conductance_dm3_per_s_bar",
       "dm^3/(s bar)",
       "sonic conductance of valve and tube (regulator.conductance_dm3_per_s_bar)",
       {0.2, 0.4, 0.8, 1.6, 3.2},
       d.regulator.conductance_dm3_per_s_bar,
       setConductance},
      {"mass_kg", "kg", "payload mass (payload.mass_kg)", {2.0, 4.0, 8.0, 16.0, 32.0}, d.payload.mass_kg, setMass},
  };
}

std::string key(const CalibratedReading& r) {
  std::string k;
  for (double v : r.plant_values) k += fmt("%g", v) + "_";
  return k;
}

}  // namespace

std::vector<CalibrationPoint> evaluateCalibrationPlant(const CalibrationSettings& s,
                                                       const std::vector<double>& values) {
  ExperimentSettings es = s.base;
  es.plant = plantWith(values);
  es.figures = false;
  es.log = nullptr;
  es.only = {"triangle"};
  es.out_dir = s.work_dir + "/" + key({values, 0});
  std::vector<CalibrationPoint> out;
  nlohmann::json table1;
  for (double ki : s.ki_grid) {
    es.ctrl.ki = ki;
    auto rep = runExperiments(es);
    if (es.table1) {
      table1 = rep.json["table1"];
      es.model_file = es.out_dir + "/model.json";
      es.table1 = false;
    }
    rep.json["table1"] = table1;
    CalibrationPoint p{{values, ki}, std::move(rep.json), 0};
    p.distance = calibrationDistance(p.summary, s.claims);
    out.push_back(std::move(p));
  }
  return out;
}

namespace {

double bestDistance(const std::vector<CalibrationPoint>& pts) {
  double best = INFINITY;
  for (const auto& p : pts) best = std::min(best, p.distance);
  return best;
}

// The plants of `batch` on s.threads threads, in the batch's order.
std::vector<std::vector<CalibrationPoint>> evaluateOnThreads(const CalibrationSettings& s,
                                                             const std::vector<std::vector<double>>& batch) {
  std::vector<std::vector<CalibrationPoint>> out(batch.size());
  std::atomic<size_t> next{0};
  std::mutex m;
  auto worker = [&] {
    for (size_t i = next++; i < batch.size(); i = next++) {
      out[i] = evaluateCalibrationPlant(s, batch[i]);
      std::lock_guard<std::mutex> lock(m);
      if (s.log)
        s.log("calibrate: plant " + key({batch[i], 0}) + " best distance " + fmt("%.3f", bestDistance(out[i])));
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::max(1, s.threads); ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  return out;
}

// The plants of `batch` evaluated by s.evaluate (or on threads); results in the cache.
void evaluateBatch(const CalibrationSettings& s, const std::vector<std::vector<double>>& batch,
                   std::map<std::string, std::vector<CalibrationPoint>>& cache) {
  auto points = s.evaluate ? s.evaluate(batch) : evaluateOnThreads(s, batch);
  if (points.size() != batch.size())
    throw std::runtime_error("calibrate: the evaluator returned another number of plants");
  for (size_t i = 0; i < batch.size(); ++i) cache[key({batch[i], 0})] = std::move(points[i]);
}

// The indices of the axes searched: s.axes by name (all when empty).
std::vector<size_t> searchedAxes(const CalibrationSettings& s) {
  const auto& axes = calibrationAxes();
  std::vector<size_t> out;
  for (size_t i = 0; i < axes.size(); ++i)
    if (s.axes.empty() || std::find(s.axes.begin(), s.axes.end(), axes[i].name) != s.axes.end()) out.push_back(i);
  for (const auto& n : s.axes)
    if (std::none_of(axes.begin(), axes.end(), [&](const CalibrationAxis& a) { return a.name == n; }))
      throw std::invalid_argument("unknown free parameter '" + n + "' (pamc calibrate --help lists them)");
  return out;
}

}  // namespace

const std::vector<CalibrationAxis>& calibrationAxes() {
  static const std::vector<CalibrationAxis> a = buildAxes();
  return a;
}

plant::PlantConfig plantWith(const std::vector<double>& values) {
  plant::PlantConfig p = plant::PlantConfig::defaults();
  const auto& axes = calibrationAxes();
  for (size_t i = 0; i < axes.size() && i < values.size(); ++i) axes[i].apply(p, values[i]);
  return p;
}

CalibrationResult runCalibration(const CalibrationSettings& s) {
  const auto searched = searchedAxes(s);
  io::makeDirectory(s.work_dir);
  const auto& axes = calibrationAxes();
  std::vector<double> current;
  for (const auto& a : axes) current.push_back(a.nominal);
  std::map<std::string, std::vector<CalibrationPoint>> cache;
  for (int pass = 0; pass < s.passes; ++pass)
    for (size_t ai : searched) {
      std::vector<std::vector<double>> batch;
      for (double v : axes[ai].values) {
        auto c = current;
        c[ai] = v;
        if (!cache.count(key({c, 0}))) batch.push_back(c);
      }
      if (s.log)
        s.log("calibrate: pass " + std::to_string(pass + 1) + ", " + axes[ai].name + ": " +
              std::to_string(batch.size()) + " new plants");
      evaluateBatch(s, batch, cache);
      double best = INFINITY;
      for (double v : axes[ai].values) {
        auto c = current;
        c[ai] = v;
        const double d = bestDistance(cache[key({c, 0})]);
        if (d < best) best = d, current = c;
      }
    }
  CalibrationResult r;
  for (auto& [k, pts] : cache)
    for (auto& p : pts) r.tried.push_back(std::move(p));
  r.best = chooseCalibration(r.tried, s.claims);
  return r;
}

nlohmann::json calibrationPointToJson(const CalibrationPoint& p) {
  return {
      {"plant_values", p.reading.plant_values}, {"ki", p.reading.ki}, {"summary", p.summary}, {"distance", p.distance}};
}

CalibrationPoint calibrationPointFromJson(const nlohmann::json& j) {
  return {{j.at("plant_values").get<std::vector<double>>(), j.at("ki").get<double>()},
          j.at("summary"),
          j.at("distance").get<double>()};
}

size_t chooseCalibration(const std::vector<CalibrationPoint>& points, const std::vector<Claim>& claims) {
  size_t best = 0;
  double d_best = INFINITY;
  for (size_t i = 0; i < points.size(); ++i) {
    const double d = calibrationDistance(points[i].summary, claims);
    if (d < d_best) d_best = d, best = i;
  }
  return best;
}

std::string formatCalibration(const CalibrationResult& r) {
  const auto& axes = calibrationAxes();
  std::vector<const Claim*> cal;
  for (const auto& c : paperClaims())
    if (c.role == ClaimRole::Calibrated && c.test.kind == ClaimTest::Kind::Near) cal.push_back(&c);
  std::string t = "|";
  for (const auto& a : axes) t += " " + a.name + " |";
  t += " ki |";
  for (const auto* c : cal) t += " " + c->id + " |";
  t += " distance |\n|";
  for (size_t i = 0; i < axes.size() + cal.size() + 2; ++i) t += "---|";
  t += "\n| paper |";
  for (size_t i = 0; i < axes.size(); ++i) t += " |";
  for (const auto* c : cal) t += " " + fmt("%.4g", c->test.paper) + " |";
  t += " |\n";
  std::vector<size_t> order(r.tried.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return r.tried[a].distance < r.tried[b].distance; });
  for (size_t i : order) {
    const auto& p = r.tried[i];
    const std::string b = i == r.best ? "**" : "";
    t += "|";
    for (double v : p.reading.plant_values) t += " " + b + fmt("%g", v) + b + " |";
    t += " " + b + fmt("%g", p.reading.ki) + b + " |";
    for (const auto* c : cal) t += " " + fmt("%.4g", numberAt(p.summary, c->test.a[0])) + " |";
    t += " " + fmt("%.3f", p.distance) + " |\n";
  }
  return t;
}

}  // namespace pamc::sim

namespace pamc::sim {

// The result of `pamc calibrate` (docs/CALIBRATION.md), per calibrationAxes(): hysteresis scale,
// travel [mm], conductance [dm^3/(s bar)], payload mass [kg]. The reading of ki it chose is
// control::kDefaultGains.ki, the default of every tool.
namespace {
const std::vector<double> kPaperPlantValues = {3.0, 3.0, 3.2, 16.0};
}

const char* const kCalibratedOn =
    "Table 1 (u0, u1, u2) and Table 2's triangle row (0.05 Hz) by `pamc calibrate`: hysteresis scale, "
    "hysteresis travel, valve conductance, payload mass and ki";

plant::PlantConfig paperPlant() { return plantWith(kPaperPlantValues); }

}  // namespace pamc::sim
