// fuzz_can_dispatch: arbitrary frame sequences on a running rig bus - the controller, sensor and valve
// nodes built from od/*.eds (PDOs mapped as shipped) on the in-process bus, in virtual time. Covers the
// dispatcher, PDO decoding, NMT, EMCY, heartbeat, SYNC and, through SDO frames, reconfiguration at run time.
//
// Input: byte 0 chooses the start (bit 0: all nodes go Operational at once, as with an NMT master);
// then operations, each an opcode byte:
//   op & 7 in 0..3  frame: 11-bit identifier ((op >> 3) & 0xF) << 7 | (next byte & 0x7F), then
//                   the DLC/flags byte and the data (see readFrame in fuzz_util.hpp)
//   op & 7 == 4     time advances by (next byte + 1) * 10 us
//   op & 7 == 5     time advances by (next byte + 1) ms
//   op & 7 == 6     time advances by (next 16 bits) % 1500 ms
//   op & 7 == 7     the last frame again, (op >> 3) + 1 times, delivered together
// Virtual time stops at 2 s per input. Nothing here may throw: the cyclic path counts problems.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "canopen/eds_dictionary.hpp"
#include "canopen/node.hpp"
#include "fuzz_util.hpp"

using namespace pamc::canopen;

namespace {

constexpr TimeUs kMaxVirtualTime = 2'000'000;  // heartbeat (250 ms) and SDO (1 s) timeouts fit
volatile std::uint64_t g_sink = 0;

const std::array<EdsFile, 3>& rigEds() {
  static const std::array<EdsFile, 3> eds = {EdsFile::load(PAMC_OD_DIR "/controller.eds"),
                                             EdsFile::load(PAMC_OD_DIR "/sensor.eds"),
                                             EdsFile::load(PAMC_OD_DIR "/valve.eds")};
  return eds;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  pamc::fuzz::Bytes in(data, size);
  const std::uint8_t setup = in.u8();

  VirtualBus bus(0, 256);
  VirtualBus::Port& tool = bus.addPort();
  std::vector<std::unique_ptr<Node>> nodes;
  std::uint64_t events = 0;
  NodeOptions options;
  options.auto_operational = (setup & 0x01) != 0;
  for (const EdsFile& eds : rigEds()) {
    VirtualBus::Port& port = bus.addPort();
    nodes.push_back(std::make_unique<Node>(dictionaryFromEds(eds, eds.node_id), eds.node_id, port, options));
    Node& n = *nodes.back();
    port.setClient(&n);
    // Hooks like an application's, so every consumer path runs to its end.
    n.onSync([&events](std::uint8_t counter, TimeUs) { events += counter; });
    n.onEmcy([&events](const EmcyMessage& m, TimeUs) { events += m.error_code; });
    n.onHeartbeat([&events](std::uint8_t id, HeartbeatEvent, NmtState, TimeUs) { events += id; });
    n.onRpdoTimeout([&events](unsigned number, TimeUs) { events += number; });
    n.onErrorFrame([&events](const Frame& f, TimeUs) { events += f.id; });
  }
  for (auto& n : nodes) n->start(bus.now());
  bus.flush();

  Frame last;
  while (!in.empty() && bus.now() < kMaxVirtualTime) {
    const std::uint8_t op = in.u8();
    switch (op & 0x07) {
      case 4: bus.advanceBy((in.u8() + 1) * TimeUs{10}); break;
      case 5: bus.advanceBy((in.u8() + 1) * TimeUs{1000}); break;
      case 6: bus.advanceBy((in.u16() % 1500) * TimeUs{1000}); break;
      case 7:
        for (int i = 0; i <= (op >> 3); ++i) tool.send(last);
        bus.flush();
        break;
      default: {
        const std::uint32_t id = (static_cast<std::uint32_t>((op >> 3) & 0x0F) << 7) | (in.u8() & 0x7Fu);
        last = pamc::fuzz::readFrame(in, id);
        tool.send(last);
        bus.flush();
        break;
      }
    }
  }
  bus.advanceBy(1000);

  g_sink = events;  // keeps the hooks' work observable
  return 0;
}
