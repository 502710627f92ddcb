// The cells of `pamc robustness` (robustness.hpp): a plant/model variant named by the axes it moves,
// its scores, and the results built from a set of cells. Shared by the runner (robustness.cpp) and the
// merge that writes the files (robustness_report.cpp).
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "sim/robustness.hpp"

namespace pamc::sim::detail {

// The "format" of a cells document (cells.json).
inline constexpr const char* kCellsFormat = "pamc-robustness-cells/1";

// A plant (and model) variant: the axes it moves away from the nominal, in the table's order.
struct Variant {
  std::vector<std::pair<const RobustnessAxis*, double>> moved;
  std::string key() const;    // "flow=0.5;mass=4;" - "" for the nominal
  std::string label() const;  // "flow 0.5 dm3/(s bar), mass 4 kg" - "nominal"
};

// Adds (axis, value) to a variant unless the value is the axis's nominal.
Variant moveTo(Variant v, const RobustnessAxis& a, double value);

// Scores by variant key.
using Cells = std::map<std::string, std::vector<RobustnessScore>>;

nlohmann::json cellsToJson(const Cells& c);
Cells cellsFromJson(const nlohmann::json& j, const std::string& where);

// Every value of every axis, one at a time; the grid of two axes.
std::vector<Variant> axisVariants(const std::vector<RobustnessAxis>& axes);
std::vector<Variant> gridVariants(const RobustnessAxis& rows, const RobustnessAxis& cols);
bool allIn(const std::vector<Variant>& variants, const Cells& cells);

// The axes' results from the cells (every axis variant among them).
std::vector<AxisResult> axisResults(const Cells& cells, const std::vector<RobustnessAxis>& axes);
// The two axes along which the mean AMC/PI ratio spreads most, strongest first (fewer when fewer ran).
std::vector<const AxisResult*> strongestTwo(const std::vector<AxisResult>& axes);
// The grid's result from the cells (every grid variant among them).
GridResult gridResult(const Cells& cells, const RobustnessAxis& rows, const RobustnessAxis& cols);

double meanAmcOverPi(const std::vector<RobustnessScore>& scores);

// "%.2f" of an identification amplitude: the tag of its files (ident_A2.00.csv, model_A2.00.json).
std::string amplitudeTag(double a);

}  // namespace pamc::sim::detail
