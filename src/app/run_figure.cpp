#include "app/run_figure.hpp"

#include <cmath>
#include <cstdio>

#include "io/measurement.hpp"
#include "report/figures.hpp"

namespace pamc::app {

double jointAngleDeg(const nodes::RigJoint& j, double y_flexor_mm) {
  return (y_flexor_mm - j.rest_mm) / j.lever_mm * 180.0 / M_PI;
}

namespace {

// The records by cycle: a row per cycle every channel has a record of, its columns per channel.
struct Columns {
  std::vector<std::string> names;
  std::vector<std::vector<double>> data;
};

Columns columnsOf(const std::vector<nodes::CycleRecord>& recs, std::size_t channels,
                  const std::vector<nodes::RigJoint>& joints) {
  Columns c;
  c.names = {"t"};
  for (std::size_t ch = 1; ch <= channels; ++ch)
    for (const char* n : {"yd", "y", "u"}) c.names.push_back(n + std::to_string(ch));
  for (std::size_t j = 1; j <= joints.size(); ++j)
    for (const char* n : {"angle_d", "angle"}) c.names.push_back(n + std::to_string(j));
  c.data.assign(c.names.size(), {});
  std::vector<const nodes::CycleRecord*> row(channels, nullptr);
  auto flush = [&] {
    for (const auto* r : row)
      if (r == nullptr) return;
    std::size_t i = 0;
    c.data[i++].push_back(row[0]->t);
    for (const auto* r : row) c.data[i++].push_back(r->yd), c.data[i++].push_back(r->y), c.data[i++].push_back(r->u);
    for (const auto& j : joints) {
      c.data[i++].push_back(jointAngleDeg(j, row[j.flexor]->yd));
      c.data[i++].push_back(jointAngleDeg(j, row[j.flexor]->y));
    }
  };
  std::uint32_t k = recs.empty() ? 0 : recs.front().k;
  for (const auto& r : recs) {
    if (r.k != k) {
      flush();
      row.assign(channels, nullptr);
      k = r.k;
    }
    if (r.channel < channels) row[r.channel] = &r;
  }
  flush();
  return c;
}

}  // namespace

void writeRunFigure(const std::string& png, const std::vector<nodes::CycleRecord>& recs, std::size_t channels,
                    const std::vector<nodes::RigJoint>& joints) {
  const Columns c = columnsOf(recs, channels, joints);
  const std::string csv = png + ".csv";
  std::vector<const std::vector<double>*> cols;
  for (const auto& d : c.data) cols.push_back(&d);
  io::writeCsvAtomic(csv, c.names, cols);
  std::vector<report::Panel> panels;
  for (std::size_t j = 1; j <= joints.size(); ++j) {
    report::Panel p{"joint " + std::to_string(j) + ": angle", "t [s]", "angle [deg]", {}};
    p.series.push_back({csv, "t", "angle_d" + std::to_string(j), "trajectory"});
    p.series.push_back({csv, "t", "angle" + std::to_string(j), "measured"});
    panels.push_back(p);
  }
  report::Panel y{"muscles: contraction", "t [s]", "y [mm]", {}}, u{"muscles: valve command", "t [s]", "u [V]", {}};
  for (std::size_t ch = 1; ch <= channels; ++ch) {
    y.series.push_back(
        {csv, "t", "yd" + std::to_string(ch), "channel " + std::to_string(ch) + " setpoint", "lines dt 2"});
    y.series.push_back({csv, "t", "y" + std::to_string(ch), "channel " + std::to_string(ch)});
    u.series.push_back({csv, "t", "u" + std::to_string(ch), "channel " + std::to_string(ch)});
  }
  panels.push_back(y);
  panels.push_back(u);
  std::string error;
  if (!report::renderFigure(png, "pamc rig run", panels, error))
    std::fprintf(stderr, "warning: no figure (%s); its data: %s\n", error.c_str(), csv.c_str());
  else
    std::printf("figure: %s (data %s)\n", png.c_str(), csv.c_str());
}

}  // namespace pamc::app
