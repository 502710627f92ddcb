// Uses the installed libraries as another project would: a PI + AMC controller on the paper's model
// closing a loop around the same model, and the controller's object dictionary from the installed EDS.
#include <cmath>
#include <cstdio>

#include "canopen/eds_dictionary.hpp"
#include "canopen/od.hpp"
#include "control/controller.hpp"
#include "control/trajectory.hpp"
#include "model/model.hpp"

int main() {
  using namespace pamc;
  control::ControllerConfig c;
  c.model = model::Model({5.0, 0.8, 20.0, 1.0, 0.3, 0.3});
  c.delay_cycles = 0;
  auto ctrl = control::makeController(control::Kind::PiAmc, c);
  // The plant: the same model, stepped by the controller's command.
  const model::Model& plant = c.model;
  model::StepContext ctx;
  ctx.Ts = c.Ts;
  model::Model::State state;
  plant.init(state, -5.0, ctx);
  double y = plant.step(state, -5.0, ctx);
  ctrl->activate(-5.0, y);
  const auto ref = control::Trajectory::sine(0.1, 5.0, 15.0);
  double se = 0;
  int n = 0;
  for (int k = 0; k < 20000; ++k) {
    const double t = k * c.Ts;
    const auto o = ctrl->update(ref.at(t), ref.at(t + c.Ts), y);
    y = plant.step(state, o.u, ctx);
    if (t > 5.0) se += (y - ref.at(t)) * (y - ref.at(t)), ++n;
  }
  const double rmse = std::sqrt(se / n);
  auto od = canopen::loadDictionary(std::string(PAMC_DATA_DIR) + "/od/controller.eds");
  const auto type = od.ref<std::uint32_t>(0x1000, 0).get();
  std::printf("tracking RMSE %.3f mm, controller device type 0x%08X\n", rmse, type);
  return rmse < 1.0 && type == 0x00100194 ? 0 : 1;
}
