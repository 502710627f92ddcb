// Speed of the 1 kHz path and of the offline tools. Run: build/tests/bench/pamc_bench
#include <benchmark/benchmark.h>

#include <cmath>

#include "control/controller.hpp"
#include "estimation/active_model.hpp"
#include "ident/identify.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"

using namespace pamc;

namespace {
model::Model paperLikeModel() { return model::Model({9.0, 1.6, 17.0, 1.0, 0.4, 0.5}); }

// The estimator's whole step (one UKF predict + update) on model m, driven by a slow sine of amplitude
// amp [V] with the position y0 + gain u.
void ukfStep(benchmark::State& state, const model::Model& m, double amp, double y0, double gain) {
  estimation::ActiveModel am;
  am.configure(m, {}, 1e-3);
  am.reset(0.0);
  int k = 0;
  for (auto _ : state) {
    const double t = (k++) * 1e-3;
    const double u = amp * std::sin(0.6 * t) + 0.2;
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
  ukfStep(state, plant::PlantConfig::defaults().truth, 0.8, 18.0, 11.0);
}
BENCHMARK(BM_UkfStepWholeModel);

// The whole PI + AMC cycle: estimator update, PI, prediction (17), compensation, saturation.
static void BM_AmcCycle(benchmark::State& state) {
  control::ControllerConfig cfg;
  cfg.model = paperLikeModel();
  auto c = control::makeController(control::Kind::PiAmc, cfg);
  c->activate(0.0, 17.0);
  int k = 0;
  for (auto _ : state) {
    const double t = (k++) * 1e-3;
    const double yd = 15 + 10 * std::sin(0.6 * t);
    auto o = c->update(yd, yd, yd + 0.1 * std::sin(7 * t));
    benchmark::DoNotOptimize(o);
  }
}
BENCHMARK(BM_AmcCycle);

// GA + Nelder-Mead identification of the six parameters on 50 000 samples of emulator data.
static void BM_Identification50k(benchmark::State& state) {
  plant::Plant p;
  const auto r = sim::runOpenLoopInput(p, control::Trajectory::sine(0.1, 2.9, 0.2), 50.0);
  io::Measurement d;
  d.t = r.t;
  d.u = r.u;
  d.y = r.y;
  d.Ts = 1e-3;
  d.source = "emulator";
  double rmse = 0;
  int gens = 0;
  for (auto _ : state) {
    const auto f = ident::fit(model::Model{}, d, {});
    rmse = f.rmse;
    gens = f.generations;
  }
  state.counters["samples"] = static_cast<double>(d.size());
  state.counters["rmse_mm"] = rmse;
  state.counters["generations"] = gens;
}
BENCHMARK(BM_Identification50k)->Unit(benchmark::kSecond)->Iterations(3);

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
    plant::Plant p;
    auto rec = sim::runClosedLoop(*c, p, run, -2.0);
    benchmark::DoNotOptimize(rec);
  }
  state.counters["x_realtime"] =
      benchmark::Counter(run.duration_s * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulationSpeed)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
