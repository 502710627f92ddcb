// Speed of the 1 kHz path and of the offline tools. Run: build/tests/bench/pamc_bench
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstddef>
#include <vector>

#include "control/controller.hpp"
#include "estimation/active_model.hpp"
#include "ident/identify.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"

using namespace pamc;

namespace {
model::Model paperLikeModel() { return model::Model({9.0, 1.6, 17.0, 1.0, 0.4, 0.5}); }

// One period of a signal, sampled at 1 kHz and read in a ring, so that the timed loops measure the
// step and not the std::sin that makes its input. The length is a power of two; the frequencies are
// whole numbers of cycles per table (`cycles` of them), so the ring has no jump where it wraps.
class Excitation {
 public:
  static constexpr std::size_t kLength = 1u << 14;  // 16.384 s
  // offset + amp sin(w1 t) + amp2 sin(w2 t), w = 2 pi cycles / 16.384 s.
  Excitation(double offset, double amp, int cycles, double amp2 = 0.0, int cycles2 = 0) : v_(kLength) {
    const double T = kLength * 1e-3;
    for (std::size_t k = 0; k < kLength; ++k) {
      const double t = k * 1e-3;
      v_[k] = offset + amp * std::sin(2.0 * M_PI * cycles * t / T) + amp2 * std::sin(2.0 * M_PI * cycles2 * t / T);
    }
  }
  double operator[](std::size_t k) const noexcept { return v_[k & (kLength - 1)]; }

 private:
  std::vector<double> v_;
};

// The estimator's whole step (one UKF predict + update) on model m, driven by a slow sine of amplitude
// amp [V] with the position y0 + gain u.
void ukfStep(benchmark::State& state, const model::Model& m, double amp, double y0, double gain) {
  estimation::ActiveModel am;
  am.configure(m, {}, 1e-3);
  am.reset(0.0);
  const Excitation input(0.2, amp, 1);  // 0.38 rad/s
  std::size_t k = 0;
  for (auto _ : state) {
    const double u = input[k++];
    auto r = am.update(u, y0 + gain * u);
    benchmark::DoNotOptimize(r);
  }
}
}  // namespace

// The paper's joint state [h, f_h].
static void BM_UkfStep(benchmark::State& state) { ukfStep(state, paperLikeModel(), 2.9, 17.0, 10.0); }
BENCHMARK(BM_UkfStep);

// The emulator's whole model: pressure lag, load, saturation, friction and the 6 Hz mass-spring, whose
// position and velocity are in the filter's state (X = [h, f_h, y_ms, v_ms]).
static void BM_UkfStepWholeModel(benchmark::State& state) {
  ukfStep(state, plant::PlantConfig::modelDefaults().truth, 0.8, 18.0, 11.0);
}
BENCHMARK(BM_UkfStepWholeModel);

// One controller's whole cycle on the paper-like model, a slow sine to track and a measured position
// with a faster ripple on it.
static void controllerCycle(benchmark::State& state, control::Kind kind) {
  control::ControllerConfig cfg;
  cfg.model = paperLikeModel();
  auto c = control::makeController(kind, cfg);
  c->activate(0.0, 17.0);
  const Excitation target(15.0, 10.0, 1);             // 0.38 rad/s
  const Excitation measured(15.0, 10.0, 1, 0.1, 18);  // + 0.1 mm at 6.9 rad/s
  std::size_t k = 0;
  for (auto _ : state) {
    const double yd = target[k];
    auto o = c->update(yd, yd, measured[k]);
    ++k;
    benchmark::DoNotOptimize(o);
  }
}

// The whole PI + AMC cycle: estimator update, PI, prediction (17), compensation, saturation.
static void BM_AmcCycle(benchmark::State& state) { controllerCycle(state, control::Kind::PiAmc); }
BENCHMARK(BM_AmcCycle);

// The whole MBC cycle (control/mbc.cpp): UKF, the modelling-error filter, the inverse's secant steps
// through the reference model's rollouts, PI, saturation.
static void BM_MbcCycle(benchmark::State& state) { controllerCycle(state, control::Kind::Mbc); }
BENCHMARK(BM_MbcCycle);

// Identification of the Bouc-Wen core (five free parameters) on 50 000 samples of emulator data
// (0.1 Hz sine, 2.9 V), validated on a record the fit never saw (0.05 Hz, 1.5 V around 1 V: another
// amplitude, frequency and offset). Counters: rmse_mm on the fitted record, val_rmse_mm on the other.
namespace {
io::Measurement emulatorRecord(const control::Trajectory& u, double seconds) {
  plant::Plant p(plant::PlantConfig::modelDefaults());
  const auto r = sim::runOpenLoopInput(p, u, seconds);
  io::Measurement d;
  d.t = r.t;
  d.u = r.u;
  d.y = r.y;
  d.Ts = 1e-3;
  d.source = "emulator";
  return d;
}

void identification(benchmark::State& state, ident::FitMethod method) {
  const io::Measurement d = emulatorRecord(control::Trajectory::sine(0.1, 2.9, 0.2), 50.0);
  const io::Measurement v = emulatorRecord(control::Trajectory::sine(0.05, 1.5, 1.0), 40.0);
  ident::FitSettings s = ident::FitSettings::forMethod(method);
  ident::FitResult f;
  for (auto _ : state) f = ident::fit(model::Model{}, d, s);
  state.counters["samples"] = static_cast<double>(d.size());
  state.counters["rmse_mm"] = f.rmse;
  state.counters["val_rmse_mm"] = ident::rmseFrom(f.model, v);
  state.counters["evaluations"] = f.evaluations;
}
}  // namespace

// The paper's method: GA (150 generations x 48), then Levenberg-Marquardt and Nelder-Mead.
static void BM_Identification50k(benchmark::State& state) { identification(state, ident::FitMethod::Ga); }
BENCHMARK(BM_Identification50k)->Unit(benchmark::kSecond)->Iterations(3);

// Levenberg-Marquardt from spread starts, then Nelder-Mead (`pamc fit --method lm`).
static void BM_Fit50kMultiStart(benchmark::State& state) { identification(state, ident::FitMethod::MultiStart); }
BENCHMARK(BM_Fit50kMultiStart)->Unit(benchmark::kMillisecond)->Iterations(5);

// Lockstep closed-loop simulation (emulator with every effect + PI + AMC): counter x_realtime is
// simulated seconds per wall-clock second.
static void BM_SimulationSpeed(benchmark::State& state) {
  control::ControllerConfig cfg;
  cfg.model = paperLikeModel();
  sim::ClosedLoopRun run;
  run.reference = control::Trajectory::triangle(0.05, 0.2, 30.0);
  run.duration_s = 20.0;
  run.preroll_s = 0.0;
  for (auto _ : state) {
    auto c = control::makeController(control::Kind::PiAmc, cfg);
    plant::Plant p(plant::PlantConfig::modelDefaults());
    auto rec = sim::runClosedLoop(*c, p, run, -2.0);
    benchmark::DoNotOptimize(rec);
  }
  state.counters["x_realtime"] =
      benchmark::Counter(run.duration_s * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulationSpeed)->Unit(benchmark::kMillisecond);

// A fit's inner loop: one simulation of a record (16 384 samples, two sines over the stroke) through the
// paper's core and one of the payload's force balances at their defaults - the effects diagnose's fits of
// a record over the whole stroke spend most of their time in. Counter: samples per second.
static void BM_SimulateBalance(benchmark::State& state, const char* effect) {
  model::Model m = paperLikeModel();
  m.addEffect(effect);
  const Excitation input(0.5, 2.5, 3, 0.8, 41);
  std::vector<double> u(Excitation::kLength), y(u.size());
  for (std::size_t k = 0; k < u.size(); ++k) u[k] = input[k];
  for (auto _ : state) {
    m.simulate(u.data(), nullptr, u.size(), 1e-3, y.data());
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["samples_per_s"] =
      benchmark::Counter(static_cast<double>(u.size() * state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_SimulateBalance, force_loop, "force_loop")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SimulateBalance, muscle_balance, "muscle_balance")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SimulateBalance, pneumatic_balance, "pneumatic_balance")->Unit(benchmark::kMicrosecond);

// Two models of one structure (k apart by 1e-4, as a Jacobian's columns are) stepped in turn, sample by
// sample, on one thread: what a fit would gain by simulating its columns in lockstep (docs/PERFORMANCE.md,
// "diagnose on the whole stroke"). Against two runs of BM_SimulateBalance.
static void BM_SimulateBalancePair(benchmark::State& state, const char* effect) {
  model::Model m = paperLikeModel();
  m.addEffect(effect);
  model::Model m2 = m;
  m2.core().k *= 1.0001;
  const Excitation input(0.5, 2.5, 3, 0.8, 41);
  std::vector<double> u(Excitation::kLength), y(u.size()), y2(u.size());
  for (std::size_t k = 0; k < u.size(); ++k) u[k] = input[k];
  for (auto _ : state) {
    model::Model::State s1, s2;
    model::StepContext c;
    c.Ts = 1e-3;
    m.init(s1, u[0], c);
    m2.init(s2, u[0], c);
    for (std::size_t i = 0; i < u.size(); ++i) {
      y[i] = m.step(s1, u[i], c);
      y2[i] = m2.step(s2, u[i], c);
    }
    benchmark::DoNotOptimize(y.data());
    benchmark::DoNotOptimize(y2.data());
  }
}
BENCHMARK_CAPTURE(BM_SimulateBalancePair, force_loop, "force_loop")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SimulateBalancePair, muscle_balance, "muscle_balance")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SimulateBalancePair, pneumatic_balance, "pneumatic_balance")->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
