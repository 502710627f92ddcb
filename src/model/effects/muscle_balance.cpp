// muscle_balance: the payload's force balance with the muscle's force-length-pressure map, braid friction
// of several break-away levels that grows with the pressure, and the end stops - the whole stroke of a
// real muscle in one balance, as force_loop is its small-signal form:
//
//   m y'' + c y' = P g(y) - W - k y - F_f,    g(y) = 1 + a1 y + a2 y^2
//
// divided by the stiffness k, with P / k = in + w (the stage input in is the static displacement the
// core delivers at g = 1, linear in the pressure; w is the weight and preload over the stiffness, so
// in + w is the pressure's force at zero contraction over the stiffness):
//
//   y'' = wn^2 ((in + w) g(y) - w - y - z) - 2 zeta wn y'
//
// - The map g: a muscle's force at a given pressure falls as it contracts (the braid's angle opens);
//   a quadratic in the contraction stands for any smooth force-length law over a stroke (Tondu-Lopez's,
//   Chou-Hannaford's, an exponential one) - the stiffening near the end of the stroke that saturation
//   approximates from the outside, and a loop whose width in millimetres changes along the stroke.
// - The friction z: a sum of three Dahl elements (a generalised Maxwell-slip model), each
//   dz_i/dy = (1 - sgn(dy) z_i) / delta_i with z_i in [-1, 1], their travels spread from delta to
//   delta * spread (several break-away levels: a short stick and a longer slide), weighted equally and
//   scaled by the normal force that presses the braid onto the tube: z = (zmax + zp max(in + w, 0)) mean(z_i).
//   With spread 1 they are one Dahl element, force_loop's friction.
// - The end stops lo, hi: a payload pushed into a stop rests on it (the contact is inelastic).
//
// With a1 = a2 = 0, zp = 0, spread = 1 and the stops outside the motion it is force_loop (with zmax 0 as
// well, mass_spring); with a payload much faster than the record (large fn) it is friction_hysteresis, the
// Dahl friction driven by the output's motion. It refines the three (Effect::refines) and absorbs
// saturation, whose stiffening its map holds (Effect::absorbs): diagnose tries it in their place, with
// saturation dropped, when the ladder ends above the noise with one of them and saturation, warm-started
// from its parameters (same names).
//
// Integration: kSubsteps per sample; each the payload's exact map at the nominal stiffness (mass_spring's)
// under the rest of the force held over the sub-step (the map's and the friction's part at the sub-step's
// start), the friction's stiffening over the sub-step taken implicitly as in force_loop (stable for any
// pre-sliding stiffness), the Dahl elements integrated exactly along the sub-step's travel.
#include "model/effects/muscle_balance.hpp"

namespace pamc::model {
std::unique_ptr<Effect> make_muscle_balance() { return std::make_unique<balance::MuscleBalance>(); }
}  // namespace pamc::model
