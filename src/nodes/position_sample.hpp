// The position of one cycle as a channel's control loop sees it (from its input driver).
#pragma once

namespace pamc::nodes {

struct PositionSample {
  double y = 0.0;       // [mm]
  double y_ctrl = 0.0;  // what the controller gets: y, or NaN when it is not to be used
  bool usable = false;  // fresh and plausible
};

}  // namespace pamc::nodes
