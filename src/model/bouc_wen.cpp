#include "model/bouc_wen.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace pamc::model {

// Bouc-Wen stability of the model core (eq. 6 with m = 1): the sign conditions of boucWenBounded, then
// the discrete form driven through sweeps and steps over the whole command range as a check.
bool boucWenStable(const BoucWenParams& p, double u_min, double u_max, std::string* why) {
  if (!boucWenBounded(p)) {
    if (why) *why = "Bouc-Wen parameters unstable: beta * sign(alpha) + gamma must be > 0 and gamma >= 0";
    return false;
  }
  double h = 0.0, u_prev = 0.0, h_max = 0.0;
  const int periods[] = {20, 200, 2000};
  for (int per : periods) {
    for (int k = 0; k < 2 * per; ++k) {
      const double ph = static_cast<double>(k % per) / per;
      const double u = u_min + (u_max - u_min) * (ph < 0.5 ? 2.0 * ph : 2.0 - 2.0 * ph);
      h = boucWenNext(p, h, u - u_prev, 0.0, 1e-3);
      u_prev = u;
      h_max = std::max(h_max, std::fabs(h));
    }
  }
  for (int k = 0; k < 200; ++k) {  // full-range steps
    const double u = (k % 2) ? u_max : u_min;
    h = boucWenNext(p, h, u - u_prev, 0.0, 1e-3);
    u_prev = u;
    h_max = std::max(h_max, std::fabs(h));
  }
  const double y = boucWenOutput(p, u_prev, h);
  if (!std::isfinite(h) || !std::isfinite(y) || h_max > 1e6) {
    if (why) *why = "Bouc-Wen model diverges on a full-range sweep";
    return false;
  }
  return true;
}

}  // namespace pamc::model
