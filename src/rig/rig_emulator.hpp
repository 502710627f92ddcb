// The emulator that plays a rig file's devices: for a rig of several channels, an encoder per channel
// (the channel's sensor slave: its EDS and node-ID) and one valve module with an output per channel
// (the valve slave's EDS and node-ID; the channels' outputs and pressure inputs consecutive sub-indices).
// A harness: nothing of it runs on a rig.
#pragma once

#include "nodes/emulator_config.hpp"
#include "nodes/rig_file.hpp"

namespace pamc::rig {

// base with the devices of rig (a rig in the one-muscle form: base as it is). Throws std::invalid_argument for a
// rig the emulator cannot play (a sensor serving two channels, devices of different EDS files, gaps in a
// module's outputs), naming the rig file.
nodes::EmulatorConfig emulatorOf(const nodes::RigFile& rig, nodes::EmulatorConfig base);

}  // namespace pamc::rig
