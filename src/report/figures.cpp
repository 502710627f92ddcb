#include "report/figures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "io/measurement.hpp"

namespace pamc::report {

namespace {
// gnuplot addresses CSV columns by number: read the header once per file.
int columnIndex(const std::string& csv, const std::string& col) {
  static std::map<std::string, std::vector<std::string>> cache;
  auto it = cache.find(csv);
  if (it == cache.end()) {
    std::ifstream f(csv);
    std::string line;
    std::getline(f, line);
    std::vector<std::string> h;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) h.push_back(c);
    it = cache.emplace(csv, h).first;
  }
  for (size_t i = 0; i < it->second.size(); ++i)
    if (it->second[i] == col) return static_cast<int>(i) + 1;
  return -1;
}

std::string quote(const std::string& s) {
  std::string o = "'";
  // A line break becomes a concatenated "\n" (single-quoted strings take no escapes).
  for (char c : s) o += c == '\'' ? std::string("''") : c == '\n' ? std::string("'.\"\\n\".'") : std::string(1, c);
  return o + "'";
}
// Writes the script beside the figure, runs gnuplot on it into tmp_png and moves that into place,
// so a failed run leaves no half-written picture.
bool runGnuplot(const std::string& script_text, const std::string& png, const std::string& tmp_png,
                std::string& error) {
  const std::string script = png + ".gp";
  {
    std::ofstream f(script);
    f << script_text;
  }
  const std::string cmd = "gnuplot " + quote(script) + " 2>" + quote(png + ".log");
  if (std::system(cmd.c_str()) != 0) {
    error = "gnuplot failed on " + script + " (see " + png + ".log)";
    std::remove(tmp_png.c_str());
    return false;
  }
  std::remove((png + ".log").c_str());
  if (std::rename(tmp_png.c_str(), png.c_str()) != 0) {
    error = "cannot move " + tmp_png + " into place";
    return false;
  }
  return true;
}
}  // namespace

bool haveGnuplot() { return std::system("command -v gnuplot >/dev/null 2>&1") == 0; }

namespace {
void plotSeries(std::ostringstream& gp, const Panel& p, bool titles) {
  gp << "plot ";
  bool first = true;
  for (const auto& s : p.series) {
    const int xc = columnIndex(s.csv, s.xcol), yc = columnIndex(s.csv, s.ycol);
    if (xc < 0 || yc < 0) continue;
    gp << (first ? "" : ", ") << quote(s.csv) << " skip 1 every " << std::max(1, p.every) << " using " << xc << ":"
       << yc << " with " << s.style;
    if (!s.color.empty()) gp << " lc rgb " << quote(s.color);
    gp << (titles ? " title " + quote(s.title) : std::string(" notitle"));
    first = false;
  }
  if (first) gp << "NaN notitle";
  gp << "\n";
}

// One panel at [y0, y0 + h) of the page (fractions), and its inset if it has one.
void plotPanel(std::ostringstream& gp, const Panel& p, double y0, double h) {
  gp << "set origin 0," << y0 << "\nset size " << (p.equal_axes ? "ratio -1" : "noratio") << " 1," << h << "\n";
  gp << "set title " << quote(p.title) << "\nset xlabel " << quote(p.xlabel) << "\nset ylabel " << quote(p.ylabel)
     << "\nset key outside right top\n";
  if (p.x_hi > p.x_lo)
    gp << "set xrange [" << p.x_lo << ":" << p.x_hi << "]\nset autoscale y\n";
  else
    gp << "set autoscale x\nset autoscale y\n";
  gp << (p.log_y ? "set logscale y\nset format y '%.0e'\n" : "unset logscale y\nset format y '% h'\n")
     << (p.log_x ? "set logscale x\n" : "unset logscale x\n");
  plotSeries(gp, p, true);
  if (p.inset_hi <= p.inset_lo) return;
  gp << "set origin 0.40," << y0 + 0.30 * h << "\nset size noratio 0.40," << 0.60 * h << "\n";
  gp << "set tics font ',8'\nset ytics autofreq\nset format y '%.1f'\n";
  gp << "set title 'zoom'\nunset xlabel\nunset ylabel\nunset key\nset object 1 rectangle from graph 0,0 to graph 1,1 "
        "behind fc rgb 'white' fs solid noborder\n";
  gp << "set xrange [" << p.inset_lo << ":" << p.inset_hi << "]\nset autoscale y\n";
  plotSeries(gp, p, false);
  gp << "unset object 1\nset tics font ',10'\nset format y '% h'\n";
}
}  // namespace

bool renderFigure(const std::string& png, const std::string& title, const std::vector<Panel>& panels,
                  std::string& error, int width, int panel_height) {
  if (!haveGnuplot()) {
    error = "gnuplot not found (apt-get install gnuplot-nox); figures skipped";
    return false;
  }
  std::ostringstream gp;
  const std::string tmp_png = png + ".tmp.png";
  const int title_px = 20 * (1 + static_cast<int>(std::count(title.begin(), title.end(), '\n'))) + 10;
  const int height = panel_height * static_cast<int>(panels.size()) + title_px;
  gp << "set terminal pngcairo size " << width << "," << height << " font 'DejaVu Sans,10'\n";
  gp << "set output " << quote(tmp_png) << "\n";
  gp << "set datafile separator ','\nset grid\nset key noenhanced\nset termoption noenhanced\n";
  gp << "set multiplot title " << quote(title) << "\n";
  const double h = static_cast<double>(panel_height) / height;
  for (size_t i = 0; i < panels.size(); ++i)
    plotPanel(gp, panels[i], 1.0 - static_cast<double>(title_px) / height - h * (i + 1), h);
  gp << "unset multiplot\nset output\n";
  return runGnuplot(gp.str(), png, tmp_png, error);
}

bool renderBars(const std::string& png, const std::string& title, const std::string& csv, int label_col, int value_col,
                const std::string& ylabel, std::string& error) {
  if (!haveGnuplot()) {
    error = "gnuplot not found (apt-get install gnuplot-nox); figures skipped";
    return false;
  }
  std::ostringstream gp;
  const std::string tmp_png = png + ".tmp.png";
  gp << "set terminal pngcairo size 1100,720 font 'DejaVu Sans,9'\nset output " << quote(tmp_png) << "\n";
  gp << "set datafile separator ','\nset termoption noenhanced\nset title " << quote(title) << "\n";
  gp << "set ylabel " << quote(ylabel) << "\nset style fill solid 0.6\nset boxwidth 0.8\nset grid ytics\n";
  gp << "set xtics rotate by -45 left\nset bmargin 18\nset rmargin 8\nunset key\nset yrange [0:*]\n";
  gp << "plot " << quote(csv) << " skip 1 using 0:" << value_col << ":xtic(" << label_col << ") with boxes\n";
  gp << "set output\n";
  return runGnuplot(gp.str(), png, tmp_png, error);
}

namespace {
// The data of one heat map as a gnuplot datablock: "col row value" per cell.
std::string heatmapBlock(const Heatmap& m, const std::string& name) {
  std::ostringstream b;
  b << name << " << EOD\n";
  for (size_t r = 0; r < m.z.size(); ++r)
    for (size_t c = 0; c < m.z[r].size(); ++c) b << c << " " << r << " " << m.z[r][c] << "\n";
  return b.str() + "EOD\n";
}

std::string ticks(const std::vector<std::string>& labels) {
  std::string t = "(";
  for (size_t i = 0; i < labels.size(); ++i) t += (i ? ", " : "") + quote(labels[i]) + " " + std::to_string(i);
  return t + ")";
}

double halfRange(const std::vector<Heatmap>& maps, double centre) {
  double h = 0.05;
  for (const auto& m : maps)
    for (const auto& row : m.z)
      for (double v : row)
        if (std::isfinite(v)) h = std::max(h, std::fabs(v - centre));
  return h;
}

std::string heatmapPanel(const Heatmap& m, const std::string& block) {
  const size_t rows = m.z.size(), cols = m.z.empty() ? 0 : m.z[0].size();
  std::ostringstream gp;
  gp << "set title " << quote(m.title) << "\nset xlabel " << quote(m.xlabel) << "\nset ylabel " << quote(m.ylabel)
     << "\n";
  gp << "set xrange [-0.5:" << cols - 0.5 << "]\nset yrange [-0.5:" << rows - 0.5 << "]\n";
  gp << "set xtics " << ticks(m.xticks) << "\nset ytics " << ticks(m.yticks) << "\n";
  gp << "plot " << block << " using 1:2:3 with image notitle, " << block
     << " using 1:2:(sprintf('%.3f', $3)) with labels font ',9' notitle\n";
  return gp.str();
}
}  // namespace

bool renderHeatmaps(const std::string& png, const std::string& title, const std::vector<Heatmap>& maps, double centre,
                    const std::string& cblabel, std::string& error, int columns) {
  if (!haveGnuplot()) {
    error = "gnuplot not found (apt-get install gnuplot-nox); figures skipped";
    return false;
  }
  const int cols = std::max(1, std::min(columns, static_cast<int>(maps.size())));
  const int rows = (static_cast<int>(maps.size()) + cols - 1) / cols;
  const double h = halfRange(maps, centre);
  std::ostringstream gp;
  const std::string tmp_png = png + ".tmp.png";
  gp << "set terminal pngcairo size " << 560 * cols << "," << 420 * rows + 60 << " font 'DejaVu Sans,10'\n";
  gp << "set output " << quote(tmp_png) << "\nset termoption noenhanced\n";
  for (size_t i = 0; i < maps.size(); ++i) gp << heatmapBlock(maps[i], "$m" + std::to_string(i));
  gp << "set palette defined (0 '#2166ac', 0.5 '#ffffff', 1 '#b2182b')\n";
  gp << "set cbrange [" << centre - h << ":" << centre + h << "]\nset cblabel " << quote(cblabel) << "\n";
  gp << "set xtics rotate by -30 left\nset tics nomirror\nset view map\n";
  gp << "set multiplot layout " << rows << "," << cols << " title " << quote(title) << "\n";
  for (size_t i = 0; i < maps.size(); ++i) gp << heatmapPanel(maps[i], "$m" + std::to_string(i));
  gp << "unset multiplot\nset output\n";
  return runGnuplot(gp.str(), png, tmp_png, error);
}

}  // namespace pamc::report
