// Bounded global and local minimisation: a real-coded genetic algorithm (the paper's
// identification method) whose population is evaluated in parallel on all cores, and a
// Nelder-Mead simplex for the local refinement after it. Both work in the box [lo, hi].
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

namespace pamc::ident {

// Must be safe to call from several threads at once; `worker` is the calling thread's index
// (0..threads-1) so it can use per-thread scratch space.
using CostFn = std::function<double(const std::vector<double>& x, int worker)>;

struct GaSettings {
  int population = 48;
  int max_generations = 150;
  int stall_generations = 30;  // stop when the best has not improved by 1e-6 relatively for this long
  double crossover_rate = 0.9;
  double mutation_rate = 0.2;  // per gene
  int elite = 2;
  std::uint64_t seed = 1;
  int threads = 0;  // 0: all cores
  // Warm start: half the first population is drawn around `start` (a point in the box); genes
  // flagged in `explore` are drawn over their whole range instead.
  std::vector<double> start;
  std::vector<bool> explore;
};

struct OptResult {
  std::vector<double> x;
  double cost = 0.0;
  std::vector<std::vector<double>> runners_up;  // GA: the next best distinct individuals, best first
  int iterations = 0;                           // generations or simplex iterations
  int evaluations = 0;
};

// progress(generation, best cost) after each generation; may be empty.
OptResult geneticAlgorithm(const CostFn& f, const std::vector<double>& lo, const std::vector<double>& hi,
                           const GaSettings& s, const std::function<void(int, double)>& progress = {});

OptResult nelderMead(const CostFn& f, const std::vector<double>& x0, const std::vector<double>& lo,
                     const std::vector<double>& hi, int max_evals, double rel_tol = 1e-12);

// Residual function for least squares: fills r (already sized) for parameters x; `worker` as in CostFn.
using ResidualFn = std::function<void(const std::vector<double>& x, std::vector<double>& r, int worker)>;

// Bounded Levenberg-Marquardt on sum(r^2)/n, Jacobian by finite differences in the unit box, its
// columns computed on `threads` workers (0..threads-1). With threads = 1 every call of f is made as
// `worker`, so that several runs can go on at once, each on its own worker's scratch space. Fixed
// parameters (lo == hi) stay put. It stops when a step lowers the cost by less than rel_tol of it.
// With undamped_check, a damped step that fails is tried once more at the start's damping before the
// damping grows, and a small gain at a grown damping is convergence only once the start's damping has
// been tried from there too (a cost rough at the scale of short steps: friction, stops).
OptResult levenbergMarquardt(const ResidualFn& f, size_t n_residuals, const std::vector<double>& x0,
                             const std::vector<double>& lo, const std::vector<double>& hi, int max_iterations,
                             int threads = 1, int worker = 0, double rel_tol = 1e-10, bool undamped_check = false);

int defaultThreads();

}  // namespace pamc::ident
