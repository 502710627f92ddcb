#include "ident/optimize.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <thread>

namespace pamc::ident {

int defaultThreads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

namespace {

double safe(double c) { return std::isfinite(c) ? c : std::numeric_limits<double>::max(); }

// Evaluates f on every row, split over `threads` workers.
void evaluateAll(const CostFn& f, const std::vector<std::vector<double>>& pop, std::vector<double>& cost, int threads) {
  const int n = static_cast<int>(pop.size());
  threads = std::max(1, std::min(threads, n));
  if (threads == 1) {
    for (int i = 0; i < n; ++i) cost[static_cast<size_t>(i)] = safe(f(pop[static_cast<size_t>(i)], 0));
    return;
  }
  std::vector<std::thread> ts;
  for (int w = 0; w < threads; ++w) {
    ts.emplace_back([&, w] {
      for (int i = w; i < n; i += threads) cost[static_cast<size_t>(i)] = safe(f(pop[static_cast<size_t>(i)], w));
    });
  }
  for (auto& t : ts) t.join();
}

}  // namespace

OptResult geneticAlgorithm(const CostFn& f, const std::vector<double>& lo, const std::vector<double>& hi,
                           const GaSettings& s, const std::function<void(int, double)>& progress) {
  const size_t d = lo.size();
  const int P = std::max(4, s.population);
  const int threads = s.threads > 0 ? s.threads : defaultThreads();
  std::mt19937_64 rng(s.seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::normal_distribution<double> N01(0.0, 1.0);

  // Genes live in [0,1]^d and are mapped to the box, so every parameter gets the same resolution.
  auto toX = [&](const std::vector<double>& g) {
    std::vector<double> x(d);
    for (size_t i = 0; i < d; ++i) x[i] = lo[i] + g[i] * (hi[i] - lo[i]);
    return x;
  };
  std::vector<std::vector<double>> genes(static_cast<size_t>(P), std::vector<double>(d));
  // Latin-hypercube start: every parameter's range is covered evenly.
  for (size_t i = 0; i < d; ++i) {
    std::vector<int> perm(static_cast<size_t>(P));
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    for (int p = 0; p < P; ++p) genes[static_cast<size_t>(p)][i] = (perm[static_cast<size_t>(p)] + U(rng)) / P;
  }
  if (!s.start.empty() && s.start.size() == d) {
    std::vector<double> g0(d);
    for (size_t i = 0; i < d; ++i)
      g0[i] = hi[i] > lo[i] ? std::clamp((s.start[i] - lo[i]) / (hi[i] - lo[i]), 0.0, 1.0) : 0.0;
    for (int p = 0; p < P / 2; ++p) {
      auto& g = genes[static_cast<size_t>(p)];
      for (size_t i = 0; i < d; ++i) {
        const bool ex = i < s.explore.size() && s.explore[i];
        if (p == 0)
          g[i] = ex ? g[i] : g0[i];
        else
          g[i] = ex ? g[i] : std::clamp(g0[i] + 0.03 * N01(rng), 0.0, 1.0);
      }
    }
  }
  std::vector<std::vector<double>> xs(static_cast<size_t>(P));
  std::vector<double> cost(static_cast<size_t>(P));
  auto evaluate = [&] {
    for (int p = 0; p < P; ++p) xs[static_cast<size_t>(p)] = toX(genes[static_cast<size_t>(p)]);
    evaluateAll(f, xs, cost, threads);
  };
  evaluate();
  OptResult r;
  r.evaluations = P;
  double best = std::numeric_limits<double>::max();
  std::vector<double> best_g;
  int stall = 0;
  int gen = 0;
  for (gen = 1; gen <= s.max_generations; ++gen) {
    std::vector<int> order(static_cast<size_t>(P));
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return cost[static_cast<size_t>(a)] < cost[static_cast<size_t>(b)]; });
    const double gb = cost[static_cast<size_t>(order[0])];
    if (gb < best * (1.0 - 1e-6) || best_g.empty()) {
      stall = 0;
    } else {
      ++stall;
    }
    if (gb < best) {
      best = gb;
      best_g = genes[static_cast<size_t>(order[0])];
    }
    if (progress) progress(gen, best);
    if (stall >= s.stall_generations) break;
    if (gen == s.max_generations) break;
    // Tournament selection of parents.
    auto pick = [&]() -> const std::vector<double>& {
      const int a = static_cast<int>(U(rng) * P) % P, b = static_cast<int>(U(rng) * P) % P;
      return genes[static_cast<size_t>(cost[static_cast<size_t>(a)] < cost[static_cast<size_t>(b)] ? a : b)];
    };
    std::vector<std::vector<double>> next;
    next.reserve(static_cast<size_t>(P));
    for (int e = 0; e < std::min(s.elite, P); ++e)
      next.push_back(genes[static_cast<size_t>(order[static_cast<size_t>(e)])]);
    // Mutation shrinks over the run: explore first, then polish.
    const double sigma = 0.15 * std::pow(0.97, gen) + 0.005;
    while (static_cast<int>(next.size()) < P) {
      const auto& a = pick();
      const auto& b = pick();
      std::vector<double> c1 = a, c2 = b;
      if (U(rng) < s.crossover_rate) {
        // BLX-0.5 blend crossover.
        for (size_t i = 0; i < d; ++i) {
          const double lo_ = std::min(a[i], b[i]), hi_ = std::max(a[i], b[i]), w = hi_ - lo_;
          c1[i] = lo_ - 0.5 * w + U(rng) * 2.0 * w;
          c2[i] = lo_ - 0.5 * w + U(rng) * 2.0 * w;
        }
      }
      for (auto* c : {&c1, &c2}) {
        for (size_t i = 0; i < d; ++i) {
          if (U(rng) < s.mutation_rate) (*c)[i] += sigma * N01(rng);
          (*c)[i] = std::clamp((*c)[i], 0.0, 1.0);
        }
        if (static_cast<int>(next.size()) < P) next.push_back(*c);
      }
    }
    genes.swap(next);
    evaluate();
    r.evaluations += P;
  }
  r.x = toX(best_g);
  r.cost = best;
  r.iterations = std::min(gen, s.max_generations);
  {
    // Distinct runners-up from the last population (for multi-start refinement).
    std::vector<int> order(static_cast<size_t>(P));
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return cost[static_cast<size_t>(a)] < cost[static_cast<size_t>(b)]; });
    std::vector<std::vector<double>> kept = {best_g};
    for (int o : order) {
      const auto& g = genes[static_cast<size_t>(o)];
      bool distinct = true;
      for (const auto& k : kept) {
        double dist = 0;
        for (size_t i = 0; i < d; ++i) dist = std::max(dist, std::fabs(g[i] - k[i]));
        if (dist < 0.05) distinct = false;
      }
      if (!distinct || !(cost[static_cast<size_t>(o)] < std::numeric_limits<double>::max())) continue;
      kept.push_back(g);
      r.runners_up.push_back(toX(g));
      if (r.runners_up.size() >= 4) break;
    }
  }
  return r;
}

OptResult nelderMead(const CostFn& f, const std::vector<double>& x0, const std::vector<double>& lo,
                     const std::vector<double>& hi, int max_evals, double rel_tol) {
  const size_t d = x0.size();
  // Work in the unit box; fixed parameters (lo == hi) are left out.
  std::vector<size_t> freeIdx;
  for (size_t i = 0; i < d; ++i)
    if (hi[i] > lo[i]) freeIdx.push_back(i);
  const size_t n = freeIdx.size();
  OptResult r;
  auto toX = [&](const std::vector<double>& g) {
    std::vector<double> x = x0;
    for (size_t k = 0; k < n; ++k) {
      const size_t i = freeIdx[k];
      x[i] = lo[i] + std::clamp(g[k], 0.0, 1.0) * (hi[i] - lo[i]);
    }
    return x;
  };
  auto cost = [&](const std::vector<double>& g) {
    ++r.evaluations;
    return safe(f(toX(g), 0));
  };
  std::vector<double> g0(n);
  for (size_t k = 0; k < n; ++k) {
    const size_t i = freeIdx[k];
    g0[k] = (x0[i] - lo[i]) / (hi[i] - lo[i]);
  }
  if (n == 0) {
    r.x = x0;
    r.cost = safe(f(x0, 0));
    return r;
  }
  double step = 0.02;
  std::vector<double> bestg = g0;
  double bestc = cost(g0);
  // Restarts with a fresh simplex around the best point guard against a collapsed simplex.
  for (int restart = 0; restart < 4 && r.evaluations < max_evals; ++restart) {
    std::vector<std::vector<double>> S(n + 1, bestg);
    std::vector<double> C(n + 1, bestc);
    for (size_t k = 0; k < n; ++k) {
      S[k + 1][k] += (bestg[k] + step <= 1.0 ? step : -step);
      C[k + 1] = cost(S[k + 1]);
    }
    while (r.evaluations < max_evals) {
      ++r.iterations;
      std::vector<size_t> o(n + 1);
      std::iota(o.begin(), o.end(), 0);
      std::sort(o.begin(), o.end(), [&](size_t a, size_t b) { return C[a] < C[b]; });
      const size_t bi = o[0], wi = o[n], si = o[n - 1];
      if (std::fabs(C[wi] - C[bi]) <= rel_tol * (std::fabs(C[bi]) + 1e-300)) break;
      double spread = 0;
      for (size_t k = 0; k < n; ++k) spread = std::max(spread, std::fabs(S[wi][k] - S[bi][k]));
      if (spread < 1e-10) break;
      std::vector<double> c(n, 0.0);
      for (size_t j = 0; j <= n; ++j)
        if (j != wi)
          for (size_t k = 0; k < n; ++k) c[k] += S[j][k] / static_cast<double>(n);
      auto along = [&](double t) {
        std::vector<double> p(n);
        for (size_t k = 0; k < n; ++k) p[k] = std::clamp(c[k] + t * (S[wi][k] - c[k]), 0.0, 1.0);
        return p;
      };
      auto xr = along(-1.0);
      const double cr = cost(xr);
      if (cr < C[bi]) {
        auto xe = along(-2.0);
        const double ce = cost(xe);
        if (ce < cr) {
          S[wi] = xe;
          C[wi] = ce;
        } else {
          S[wi] = xr;
          C[wi] = cr;
        }
      } else if (cr < C[si]) {
        S[wi] = xr;
        C[wi] = cr;
      } else {
        auto xc = along(cr < C[wi] ? -0.5 : 0.5);
        const double cc = cost(xc);
        if (cc < std::min(cr, C[wi])) {
          S[wi] = xc;
          C[wi] = cc;
        } else {
          for (size_t j = 0; j <= n; ++j) {
            if (j == bi) continue;
            for (size_t k = 0; k < n; ++k) S[j][k] = S[bi][k] + 0.5 * (S[j][k] - S[bi][k]);
            C[j] = cost(S[j]);
          }
        }
      }
    }
    size_t b = 0;
    for (size_t j = 1; j <= n; ++j)
      if (C[j] < C[b]) b = j;
    const bool improved = C[b] < bestc * (1.0 - 1e-9);
    if (C[b] < bestc) {
      bestc = C[b];
      bestg = S[b];
    }
    if (!improved && restart > 0) break;
    step *= 0.25;
  }
  r.x = toX(bestg);
  r.cost = bestc;
  return r;
}

namespace {

// One bounded Levenberg-Marquardt run (levenbergMarquardt below). Its parameters live in the unit box
// g in [0,1]^n of the free ones; `step()` is one iteration: the Jacobian, the normal equations and the
// damping's ladder.
class LmRun {
 public:
  LmRun(const ResidualFn& f, size_t m, const std::vector<double>& x0, const std::vector<double>& lo,
        const std::vector<double>& hi, int threads, int worker, double rel_tol, bool undamped_check)
      : f_(f), m_(m), x0_(x0), lo_(lo), hi_(hi), rel_tol_(rel_tol), undamped_check_(undamped_check) {
    for (size_t i = 0; i < x0.size(); ++i)
      if (hi[i] > lo[i]) free_.push_back(i);
    n_ = static_cast<int>(free_.size());
    g_.resize(n_);
    for (int k = 0; k < n_; ++k) {
      const size_t i = free_[static_cast<size_t>(k)];
      g_(k) = std::clamp((x0[i] - lo[i]) / (hi[i] - lo[i]), 0.0, 1.0);
    }
    threads = std::max(1, threads);
    main_worker_ = threads == 1 ? worker : 0;
    threads_ = std::max(1, std::min(threads, n_));
    r_.resize(m);
    trial_r_.assign(2, std::vector<double>(m));
    f_(toX(g_), r_, main_worker_);
    ++evaluations_;
    c_ = cost(r_);
  }

  int freeCount() const { return n_; }
  int evaluations() const { return evaluations_; }
  double bestCost() const { return c_; }
  std::vector<double> bestX() const { return toX(g_); }

  // One iteration. Returns false when the run is over: converged, or no rung of the ladder lowered the cost.
  bool step() {
    jacobian();
    if (!normalEquations()) return false;
    return descend();
  }

 private:
  static constexpr double kLambda0 = 1e-3;  // the damping a run starts with: nearly Gauss-Newton's step
  static constexpr double kDiff = 1e-6;     // the finite differences' step in the unit box

  // A rung of the damping's ladder: its damping, and the point its step reaches (empty: not finite).
  struct Rung {
    double lam = 0;
    bool undamped = false;
    Eigen::VectorXd g;
  };

  std::vector<double> toX(const Eigen::VectorXd& g) const {
    std::vector<double> x = x0_;
    for (int k = 0; k < n_; ++k) {
      const size_t i = free_[static_cast<size_t>(k)];
      x[i] = lo_[i] + std::clamp(g(k), 0.0, 1.0) * (hi_[i] - lo_[i]);
    }
    return x;
  }

  double cost(const std::vector<double>& v) const {
    double s = 0;
    for (double e : v) s += e * e;
    return std::isfinite(s) ? s / static_cast<double>(m_) : std::numeric_limits<double>::max();
  }

  // Jacobian columns by forward (or, at the upper bound, backward) differences, each column taken by the
  // next free worker: a column reruns only the stages its parameter enters, so their costs differ.
  void jacobian() {
    cols_.resize(static_cast<size_t>(n_), std::vector<double>(m_));
    steps_.resize(static_cast<size_t>(n_));
    std::atomic<int> next{0};
    auto work = [&](int w) {
      for (int k = next++; k < n_; k = next++) {
        Eigen::VectorXd gp = g_;
        const double st = g_(k) + kDiff <= 1.0 ? kDiff : -kDiff;
        gp(k) += st;
        steps_[static_cast<size_t>(k)] = st;
        f_(toX(gp), cols_[static_cast<size_t>(k)], w);
      }
    };
    if (threads_ == 1) {
      work(main_worker_);
    } else {
      std::vector<std::thread> ts;
      for (int w = 1; w < threads_; ++w) ts.emplace_back(work, w);
      work(0);
      for (auto& t : ts) t.join();
    }
    evaluations_ += n_;
  }

  // The derivatives into one column-major matrix, then the normal equations by Eigen's blocked,
  // vectorised products (a scalar loop per pair of columns cost as much as the simulations).
  bool normalEquations() {
    J_.resize(static_cast<Eigen::Index>(m_), n_);
    for (int a = 0; a < n_; ++a) {
      const auto& ca = cols_[static_cast<size_t>(a)];
      const double sa = steps_[static_cast<size_t>(a)];
      double* ja = J_.col(a).data();
      for (size_t i = 0; i < m_; ++i) ja[i] = (ca[i] - r_[i]) / sa;
    }
    const Eigen::Map<const Eigen::VectorXd> rv(r_.data(), static_cast<Eigen::Index>(m_));
    A_ = Eigen::MatrixXd::Zero(n_, n_);
    A_.selfadjointView<Eigen::Lower>().rankUpdate(J_.transpose());
    A_.triangularView<Eigen::StrictlyUpper>() = A_.transpose();
    b_ = J_.transpose() * rv;
    return A_.allFinite() && b_.allFinite();
  }

  // The damping's ladder: lambda, then lambda times 4, 16, ... (times 10 past a step that is not finite).
  // With undamped_check, when lambda has grown past the start's, the start's own is tried second. A
  // friction's or a stop's kinks make the cost rough at the scale of a short damped step but not of a
  // Gauss-Newton one: a run whose damped steps gained ever less stalled at lambda 1e8 and stopped as
  // converged, where from the same point a step at the start's lambda lowered the cost by 9 %
  // (pneumatic_balance on the physics plant's whole stroke, docs/MODELING.md). Every rung is the one taken
  // when all before it failed, so the ladder is known before any of its points is evaluated.
  std::vector<Rung> ladder() const {
    const bool rescue = undamped_check_ && lambda_ > kLambda0;
    std::vector<Rung> rungs;
    double damped = lambda_;
    for (int tries = 0; tries < 12 + (rescue ? 1 : 0); ++tries) {
      Rung rung;
      rung.undamped = rescue && tries == 1;
      rung.lam = rung.undamped ? kLambda0 : damped;
      Eigen::MatrixXd M = A_;
      for (int k = 0; k < n_; ++k) M(k, k) += rung.lam * std::max(A_(k, k), 1e-12);
      const Eigen::VectorXd d = M.ldlt().solve(-b_);
      if (d.allFinite()) rung.g = (g_ + d).cwiseMax(0.0).cwiseMin(1.0);
      if (!rung.undamped) damped *= d.allFinite() ? 4.0 : 10.0;
      if (d.allFinite()) rungs.push_back(std::move(rung));
    }
    return rungs;
  }

  // The ladder's points evaluated two at a time where two workers are given (the second on the core the
  // Jacobian's columns had): the first that lowers the cost is taken, as one at a time would take it.
  bool descend() {
    const std::vector<Rung> rungs = ladder();
    const bool pairs = threads_ > 1;
    for (size_t k = 0; k < rungs.size(); k += pairs ? 2 : 1) {
      const size_t count = pairs ? std::min<size_t>(2, rungs.size() - k) : 1;
      double cn[2];
      evaluate(rungs, k, count, cn);
      for (size_t j = 0; j < count; ++j)
        if (cn[j] < c_) return accept(rungs[k + j], cn[j], j);
    }
    return false;
  }

  void evaluate(const std::vector<Rung>& rungs, size_t k, size_t count, double* cn) {
    auto one = [&](size_t j, int w) {
      f_(toX(rungs[k + j].g), trial_r_[j], w);
      cn[j] = cost(trial_r_[j]);
    };
    if (count == 2) {
      std::thread second(one, 1, 1);
      one(0, main_worker_);
      second.join();
    } else {
      one(0, main_worker_);
    }
    evaluations_ += static_cast<int>(count);
  }

  bool accept(const Rung& rung, double cn, size_t j) {
    const double rel = (c_ - cn) / std::max(c_, 1e-300);
    g_ = rung.g;
    r_.swap(trial_r_[j]);
    c_ = cn;
    lambda_ = std::max(rung.lam / 3.0, 1e-9);
    if (rel >= rel_tol_) {
      confirming_ = false;
      return true;
    }
    // A small gain of a damped step: converged once the start's damping has gained little from here too.
    if (undamped_check_ && rung.lam > kLambda0 && !confirming_) {
      confirming_ = true;
      lambda_ = kLambda0;
      return true;
    }
    return false;
  }

  const ResidualFn& f_;
  size_t m_;
  const std::vector<double>& x0_;
  const std::vector<double>& lo_;
  const std::vector<double>& hi_;
  double rel_tol_;
  bool undamped_check_;
  std::vector<size_t> free_;
  int n_ = 0;
  int main_worker_ = 0;
  int threads_ = 1;
  int evaluations_ = 0;
  Eigen::VectorXd g_;
  std::vector<double> r_;
  std::vector<std::vector<double>> trial_r_;  // the points of the ladder being evaluated
  double c_ = 0;
  double lambda_ = kLambda0;
  bool confirming_ = false;  // the last step's small gain is being checked at the start's damping
  std::vector<std::vector<double>> cols_;
  std::vector<double> steps_;
  Eigen::MatrixXd J_;  // the Jacobian, column k = d r / d g_k
  Eigen::MatrixXd A_;
  Eigen::VectorXd b_;
};

}  // namespace

OptResult levenbergMarquardt(const ResidualFn& f, size_t m, const std::vector<double>& x0,
                             const std::vector<double>& lo, const std::vector<double>& hi, int max_iterations,
                             int threads, int worker, double rel_tol, bool undamped_check) {
  LmRun run(f, m, x0, lo, hi, threads, worker, rel_tol, undamped_check);
  OptResult res;
  if (run.freeCount() > 0)
    for (int it = 0; it < max_iterations; ++it) {
      ++res.iterations;
      if (!run.step()) break;
    }
  res.x = run.bestX();
  res.cost = run.bestCost();
  res.evaluations = run.evaluations();
  return res;
}

}  // namespace pamc::ident
