// Figures through gnuplot: a script written next to the data, run once. Missing gnuplot is a
// warning, not an error: the CSVs are the results, the pictures are for people.
#pragma once

#include <string>
#include <vector>

namespace pamc::report {

struct Series {
  std::string csv;         // data file
  std::string xcol, ycol;  // column names in the CSV header
  std::string title;
  std::string style = "lines";
  std::string color = "";  // gnuplot colour ("#d62728"); empty: gnuplot's sequence
};

struct Panel {
  std::string title, xlabel, ylabel;
  std::vector<Series> series;
  bool equal_axes = false;
  double x_lo = 0, x_hi = 0;  // x range when x_hi > x_lo (a zoom), else automatic
  // An inset in the panel's upper right showing the same series zoomed to [inset_lo, inset_hi] in x
  // (the paper's Fig. 11) when inset_hi > inset_lo.
  double inset_lo = 0, inset_hi = 0;
  bool log_y = false, log_x = false;  // logarithmic axes (spectra)
  int every = 10;                     // plot every n-th row (1 for spectra, whose lines are one bin wide)
};

// Renders panels stacked vertically into a PNG (pngcairo). Returns false with `error` set when
// gnuplot is missing or fails.
bool renderFigure(const std::string& png, const std::string& title, const std::vector<Panel>& panels,
                  std::string& error, int width = 1000, int panel_height = 330);

// A bar chart of one CSV column against a label column (1-based column numbers), one bar per row.
bool renderBars(const std::string& png, const std::string& title, const std::string& csv, int label_col, int value_col,
                const std::string& ylabel, std::string& error);

// A heat map: z[row][col], rows along y (row 0 at the bottom) and columns along x, named by the ticks.
struct Heatmap {
  std::string title, xlabel, ylabel;
  std::vector<std::string> xticks, yticks;  // one per column / row
  std::vector<std::vector<double>> z;
};

// Heat maps in one PNG, `columns` side by side, every cell coloured and labelled with its value. One colour
// scale for all, diverging around `centre` (white), blue below and red above, symmetric: centre +- the
// largest distance from it in the data (at least 0.05). Returns false with `error` set like renderFigure.
bool renderHeatmaps(const std::string& png, const std::string& title, const std::vector<Heatmap>& maps, double centre,
                    const std::string& cblabel, std::string& error, int columns = 2);

bool haveGnuplot();

}  // namespace pamc::report
