#include "ident/identify.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace pamc::ident {

namespace {
double range(const std::vector<double>& v) {
  const auto [a, b] = std::minmax_element(v.begin(), v.end());
  return *b - *a;
}
}  // namespace

Bounds dataBounds(const model::Model& m, const io::Measurement& d) {
  const auto specs = m.paramSpecs();
  Bounds b;
  for (const auto& s : specs) {
    b.lo.push_back(s.lo);
    b.hi.push_back(s.hi);
  }
  const double ru = std::max(range(d.u), 1e-12);
  const double ry = std::max(range(d.y), 1e-12);
  const auto [ymin, ymax] = std::minmax_element(d.y.begin(), d.y.end());
  double umax = 0;
  for (double u : d.u) umax = std::max(umax, std::fabs(u));
  // The search runs over a = k rho and c = k (1 - rho) - the gains of u and of h in the output,
  // which the data bound directly - instead of (k, rho), whose product couples them.
  // With alpha fixed at +1 a lagging (counter-clockwise) loop has c < 0 (see bouc_wen.hpp).
  const double kmax = 4.0 * ry / ru;
  b.lo[0] = -kmax;
  b.hi[0] = kmax;  // a = k rho
  b.lo[1] = -10.0 * ry / ru;
  b.hi[1] = 10.0 * ry / ru;  // c = k (1 - rho)
  b.lo[2] = *ymin - kmax * umax - ry;
  b.hi[2] = *ymax + kmax * umax + ry;  // b
  b.lo[3] = b.hi[3] = 1.0;           // alpha fixed: scale of h
  b.lo[4] = -10.0 / ru;
  b.hi[4] = 10.0 / ru;  // beta
  b.lo[5] = -10.0 / ru;
  b.hi[5] = 10.0 / ru;  // gamma
  // Effect parameters in output units scale with the output range.
  for (size_t i = model::kBoucWenParams; i < specs.size(); ++i) {
    if (specs[i].unit.rfind("y-unit", 0) == 0) {
      const double s = ry / 40.0;  // catalogue bounds are written for a 40 mm stroke
      b.lo[i] *= s;
      b.hi[i] *= s;
    }
  }
  return b;
}

void searchToModel(const std::vector<double>& x, std::vector<double>& p) {
  p = x;
  const double k = x[0] + x[1];
  p[0] = k;
  p[1] = std::fabs(k) > 1e-300 ? x[0] / k : 1.0;
}

double mse(const model::Model& m, const io::Measurement& d) {
  const auto* load = d.column("load");
  std::vector<double> y(d.size());
  m.simulate(d.u.data(), load ? load->data() : nullptr, d.size(), d.Ts, y.data());
  double s = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    const double e = y[i] - d.y[i];
    s += e * e;
  }
  return s / static_cast<double>(y.size());
}

FitResult fit(const model::Model& structure, const io::Measurement& d, const FitSettings& s,
              const std::function<void(const char*, int, double)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  if (structure.needsLoad() && !d.has("load"))
    throw std::invalid_argument(d.source + ": the model has the 'load' effect but the data has no 'load' column");
  const Bounds b = dataBounds(structure, d);
  const int threads = s.ga.threads > 0 ? s.ga.threads : defaultThreads();
  const auto* load = d.column("load");
  // Per-thread model and output buffer: the cost runs allocation-free.
  std::vector<model::Model> models(static_cast<size_t>(threads), structure);
  std::vector<std::vector<double>> ybuf(static_cast<size_t>(threads), std::vector<double>(d.size()));
  const double* lp = load ? load->data() : nullptr;
  std::vector<std::vector<double>> pbuf(static_cast<size_t>(threads));
  CostFn cost = [&](const std::vector<double>& x, int w) {
    auto& m = models[static_cast<size_t>(w)];
    auto& p = pbuf[static_cast<size_t>(w)];
    searchToModel(x, p);
    m.setParams(p);
    auto& y = ybuf[static_cast<size_t>(w)];
    m.simulate(d.u.data(), lp, d.size(), d.Ts, y.data());
    double acc = 0;
    for (size_t i = 0; i < y.size(); ++i) {
      const double e = y[i] - d.y[i];
      acc += e * e;
    }
    return acc / static_cast<double>(y.size());
  };
  GaSettings gs = s.ga;
  gs.threads = threads;
  OptResult r = geneticAlgorithm(cost, b.lo, b.hi, gs, [&](int g, double c) {
    if (progress) progress("ga", g, std::sqrt(c));
  });
  FitResult out;
  out.generations = r.iterations;
  out.evaluations = r.evaluations;
  if (s.refine) {
    OptResult n = nelderMead(cost, r.x, b.lo, b.hi, s.refine_evals);
    out.evaluations += n.evaluations;
    if (n.cost <= r.cost) r = n;
    if (progress) progress("refine", n.iterations, std::sqrt(r.cost));
  }
  out.model = structure;
  std::vector<double> p;
  searchToModel(r.x, p);
  out.model.setParams(p);
  out.mse = r.cost;
  out.rmse = std::sqrt(r.cost);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace pamc::ident
