#include "sim/robustness_cells.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "io/json_fields.hpp"
#include "io/text.hpp"

namespace pamc::sim::detail {

using io::fmt;

std::string Variant::key() const {
  std::string k;
  for (const auto& [a, v] : moved) k += a->name + "=" + fmt("%.9g", v) + ";";
  return k;
}

std::string Variant::label() const {
  std::string l;
  for (const auto& [a, v] : moved) l += (l.empty() ? "" : ", ") + a->name + " " + fmt("%g", v) + " " + a->unit;
  return l.empty() ? "nominal" : l;
}

Variant moveTo(Variant v, const RobustnessAxis& a, double value) {
  if (value != a.nominal) v.moved.emplace_back(&a, value);
  return v;
}

// ---------------------------------------------------------------- cells as JSON (doubles round-trip)

namespace {

nlohmann::json numberOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

double numberAt(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key)) io::json_fields::fail(where, std::string("'") + key + "' is missing");
  return j.at(key).is_null() ? NAN : io::json_fields::number(j.at(key), key, where);
}

RobustnessScore scoreFromJson(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object() || !j.contains("trajectory") || !j.at("trajectory").is_string())
    io::json_fields::fail(where, "a score without its trajectory");
  return {j.at("trajectory").get<std::string>(),
          numberAt(j, "pi", where),
          numberAt(j, "eso", where),
          numberAt(j, "amc", where),
          numberAt(j, "mbc", where),
          numberAt(j, "scored_from_s", where)};
}

}  // namespace

nlohmann::json cellsToJson(const Cells& c) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, scores] : c) {
    nlohmann::json row = nlohmann::json::array();
    for (const auto& sc : scores)
      row.push_back({{"trajectory", sc.trajectory},
                     {"pi", sc.pi},
                     {"eso", sc.eso},
                     {"amc", sc.amc},
                     {"mbc", sc.mbc},
                     {"scored_from_s", numberOrNull(sc.scored_from_s)}});
    j[key] = row;
  }
  return j;
}

Cells cellsFromJson(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) io::json_fields::fail(where, "'cells' must be an object");
  Cells c;
  for (const auto& [key, row] : j.items()) {
    if (!row.is_array()) io::json_fields::fail(where, "cell '" + key + "' must be a list of scores");
    auto& scores = c[key];
    for (const auto& sc : row) scores.push_back(scoreFromJson(sc, where + ": cell '" + key + "'"));
  }
  return c;
}

// ---------------------------------------------------------------- variants

std::vector<Variant> axisVariants(const std::vector<RobustnessAxis>& axes) {
  std::vector<Variant> v;
  for (const auto& a : axes)
    for (double value : a.values) v.push_back(moveTo({}, a, value));
  return v;
}

std::vector<Variant> gridVariants(const RobustnessAxis& rows, const RobustnessAxis& cols) {
  std::vector<Variant> v;
  for (double r : rows.values)
    for (double c : cols.values) v.push_back(moveTo(moveTo({}, rows, r), cols, c));
  return v;
}

bool allIn(const std::vector<Variant>& variants, const Cells& cells) {
  return std::all_of(variants.begin(), variants.end(), [&](const Variant& v) { return cells.count(v.key()) > 0; });
}

// ---------------------------------------------------------------- results

double meanAmcOverPi(const std::vector<RobustnessScore>& scores) {
  double sum = 0.0;
  for (const auto& sc : scores) sum += sc.amcOverPi();
  return scores.empty() ? NAN : sum / static_cast<double>(scores.size());
}

std::vector<AxisResult> axisResults(const Cells& cells, const std::vector<RobustnessAxis>& axes) {
  std::vector<AxisResult> out;
  for (const auto& a : axes) {
    AxisResult r{a, {}, {}, 0.0};
    for (double v : a.values) {
      r.scores.push_back(cells.at(moveTo({}, a, v).key()));
      r.mean_amc_over_pi.push_back(meanAmcOverPi(r.scores.back()));
    }
    const auto [lo, hi] = std::minmax_element(r.mean_amc_over_pi.begin(), r.mean_amc_over_pi.end());
    r.spread = *hi - *lo;
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<const AxisResult*> strongestTwo(const std::vector<AxisResult>& axes) {
  std::vector<const AxisResult*> order;
  for (const auto& a : axes) order.push_back(&a);
  std::stable_sort(order.begin(), order.end(),
                   [](const AxisResult* x, const AxisResult* y) { return x->spread > y->spread; });
  if (order.size() > 2) order.resize(2);
  return order;
}

GridResult gridResult(const Cells& cells, const RobustnessAxis& rows, const RobustnessAxis& cols) {
  GridResult g{rows.name, cols.name, rows.values, cols.values, {}};
  for (double r : rows.values) {
    g.scores.emplace_back();
    for (double c : cols.values) g.scores.back().push_back(cells.at(moveTo(moveTo({}, rows, r), cols, c).key()));
  }
  return g;
}

std::string amplitudeTag(double a) { return fmt("%.2f", a); }

}  // namespace pamc::sim::detail
