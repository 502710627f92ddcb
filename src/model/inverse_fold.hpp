// Whether a model's inverse folds (docs/CONTROL.md, "A model whose inverse folds"): its hysteresis - the
// Bouc-Wen core, what a controller that inverts the model has to undo; the input effects are monotone maps and
// lags, the output effects the payload's dynamics and monotone maps - turning against its settled gain along
// a branch. A fitted core
// whose h term outweighs its u term with the other sign (k (1 - rho) against k rho) falls where h crosses
// 0 while the command rises; the inverse jumps from one branch to the other there, and so does a feedforward
// from it (the MBC's, src/control/mbc.cpp).
#pragma once

#include <string>

#include "model/model.hpp"

namespace pamc::model {

struct InverseFold {
  bool folds = false;
  double least = 1.0;     // the least slope along a branch over the settled gain (1 for a straight core)
  double at_input = 0.0;  // ... at this input of the core (a command through the input effects at rest)
  double gain = 0.0;      // the settled gain: a rising branch end to end [output units per unit of that input]
};

// The core swept slowly over the inputs [u_lo, u_hi] settle to through the input effects, twice (up, down, up,
// down); judged on the second sweep. Allocates: not for a
// control cycle.
InverseFold inverseFold(const Model& m, double u_lo, double u_hi);

// One line: "its inverse does not fold (...)" or "its inverse folds: ...".
std::string describeInverseFold(const InverseFold& f);

}  // namespace pamc::model
