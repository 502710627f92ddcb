// The experiments' figures: one colour per controller in every panel and figure, titles that carry
// the readings, Fig. 11 as the paper draws it (a panel per controller with a zoomed inset).
#include "report/figures.hpp"
#include "sim/experiment_steps.hpp"

namespace pamc::sim::detail {

namespace {

using report::Panel;
using report::Series;

constexpr const char* kDesired = "#000000";
constexpr const char* kMeasured = "#7f7f7f";

std::string csvOf(const Context& x, const std::string& tag, control::Kind k) {
  return x.dir + tag + "_" + control::toString(k) + ".csv";
}

void render(const Context& x, const std::string& png, const std::string& title, const std::vector<Panel>& panels) {
  std::string err;
  if (!report::renderFigure(png, title, panels, err)) x.warn(err);
}

Panel timePanel(const Context& x, const std::string& tag, const std::vector<control::Kind>& kinds) {
  Panel p{"(a) time plot", "t [s]", "y [mm]", {}};
  p.series.push_back({csvOf(x, tag, kinds.front()), "t", "yd", "desired", "lines", kDesired});
  for (auto k : kinds) p.series.push_back({csvOf(x, tag, k), "t", "y", label(k), "lines", colour(k)});
  return p;
}

Panel loopPanel(const Context& x, const std::string& tag, const std::vector<control::Kind>& kinds) {
  Panel p{"(b) hysteresis compensation: y against yd", "yd [mm]", "y [mm]", {}};
  for (auto k : kinds) p.series.push_back({csvOf(x, tag, k), "yd", "y", label(k), "lines", colour(k)});
  return p;
}

Panel stepsPanel(const Context& x, const std::string& tag, const std::vector<control::Kind>& kinds) {
  // y against yd is degenerate for steps: every step's response overlaid instead.
  Panel p{"(b) every step overlaid: response in % of the jump", "time since the step [s]", "response [%]", {}};
  for (auto k : kinds)
    p.series.push_back({csvOf(x, tag + "_steps", k), "t_step", "response_pct", label(k), "lines", colour(k)});
  p.x_lo = 0;
  p.x_hi = 2.0;
  return p;
}

Panel voltagePanel(const Context& x, const std::string& tag, const std::vector<control::Kind>& kinds) {
  Panel p{"(c) control voltages: nominal u_n (solid), compensation u_c (dashed)", "t [s]", "u [V]", {}};
  for (auto k : kinds) {
    const std::string csv = csvOf(x, tag, k);
    if (k == control::Kind::PiAmc || k == control::Kind::PidEso || k == control::Kind::Mbc) {
      p.series.push_back({csv, "t", "u_n", std::string(label(k)) + " u_n", "lines", colour(k)});
      p.series.push_back({csv, "t", "u_c", std::string(label(k)) + " u_c", "lines dashtype 2", colour(k)});
    } else if (k == control::Kind::PI) {
      p.series.push_back({csv, "t", "u", "PID u", "lines", colour(k)});
    }
  }
  return p;
}

}  // namespace

const char* label(control::Kind k) {
  switch (k) {
    case control::Kind::OpenLoop: return "Open loop";
    case control::Kind::PI: return "PID";
    case control::Kind::PidEso: return "PID+ESO";
    case control::Kind::PiAmc: return "PID+AMC";
    case control::Kind::Input: return "input";
    case control::Kind::Mbc: return "MBC";
  }
  return "?";
}

const char* colour(control::Kind k) {
  switch (k) {
    case control::Kind::OpenLoop: return "#8c564b";
    case control::Kind::PI: return "#1f77b4";
    case control::Kind::PidEso: return "#2ca02c";
    case control::Kind::PiAmc: return "#d62728";
    case control::Kind::Input: return "#7f7f7f";
    case control::Kind::Mbc: return "#9467bd";
  }
  return "#000000";
}

void figureTracking(const Context& x, const std::string& tag, const std::string& title,
                    const std::vector<control::Kind>& kinds, bool steps) {
  if (!x.figures) return;
  render(x, x.dir + tag + ".png", title + "\n" + x.readings_line,
         {timePanel(x, tag, kinds), steps ? stepsPanel(x, tag, kinds) : loopPanel(x, tag, kinds),
          voltagePanel(x, tag, kinds)});
}

void figurePayload(const Context& x, const std::string& tag, const std::string& title,
                   const std::vector<control::Kind>& kinds, double t_event) {
  if (!x.figures) return;
  std::vector<Panel> panels;
  const char letter[] = "abc";
  for (size_t i = 0; i < kinds.size(); ++i) {
    const auto k = kinds[i];
    Panel p{std::string("(") + letter[i % 3] + ") " + label(k), "t [s]", "y [mm]", {}};
    p.series.push_back({csvOf(x, tag, k), "t", "yd", "desired", "lines", kDesired});
    p.series.push_back({csvOf(x, tag, k), "t", "y", label(k), "lines", colour(k)});
    p.inset_lo = t_event - 0.2;
    p.inset_hi = t_event + 2.0;
    panels.push_back(p);
  }
  render(x, x.dir + tag + ".png", title + "\n" + x.readings_line, panels);
}

void figureTable1(const Context& x, const std::string& csv, const std::string& png, const std::string& title) {
  if (!x.figures) return;
  Panel time{"time plot",
             "t [s]",
             "y [mm]",
             {{csv, "t", "y", "measured", "lines", kMeasured},
              {csv, "t", "y_reference", "reference model", "lines", "#9467bd"},
              {csv, "t", "y_active", "active model (UKF posterior)", "lines", colour(control::Kind::PiAmc)}}};
  Panel loop{"hysteresis loop",
             "u [V]",
             "y [mm]",
             {{csv, "u", "y", "measured", "lines", kMeasured},
              {csv, "u", "y_reference", "reference model", "lines", "#9467bd"}}};
  render(x, png, title + "\nplant: " + plantText(x.s.plant), {time, loop});
}

}  // namespace pamc::sim::detail
