// Whether a model comes to rest under a held command (docs/CONTROL.md, "A model that does not come to
// rest"). A muscle under a held valve command comes to rest; a fitted model need not. The fit only asks it to
// follow the record, and a record that keeps moving (the paper's sinusoids) never holds a command. At the
// period it was identified on, a model can then swing under a held command - a payload's ringing with
// next to no damping against the pressure's flow and the stops. A controller that inverts it swings with it.
// Judged at the controller's own period: a model's steps depend on it.
#pragma once

#include <string>

#include "model/model.hpp"

namespace pamc::model {

struct HeldRest {
  bool rests = true;
  double swing = 0.0;       // the largest swing of the output over the last quarter of a hold [output units]
  double at_command = 0.0;  // ... under this command
  double span = 0.0;        // the span the swing is judged against (the identified output range's, else the holds')
  double Ts = 0.0;          // the period it was judged at [s]
};

// The model from rest at u_lo through kLevels commands up to u_hi and back down, each held for kHoldSeconds at
// the period Ts; it rests where no hold's output swings over more than kRestShare of the span over the hold's
// last quarter, and stays finite. Allocates: not for a control cycle.
// span > 0 judges the swing against it instead (a fit's record's output span, before the model has a range).
HeldRest heldRest(const Model& m, double Ts, double u_lo, double u_hi, double span = 0.0);

// One line: "it comes to rest under a held command ..." or "it does not come to rest ...".
std::string describeHeldRest(const HeldRest& h);

}  // namespace pamc::model
