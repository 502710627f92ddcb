// Exact bus time of classic CAN 2.0 frames, for bus-load accounting from the frames actually sent:
// the bit count includes the stuff bits the transmitter inserts, which depend on the identifier, the
// data and the CRC, so they are computed rather than estimated (the ~10 % rule of thumb in
// VirtualBus::frameTimeUs and nodes::frameBits is off by up to 20 % for frames full of zeros).
#pragma once

#include <cstdint>

#include "canopen/frame.hpp"

namespace pamc::canopen {

// Unstuffed bits after the CRC sequence: CRC delimiter 1, ACK slot 1, ACK delimiter 1, EOF 7.
inline constexpr unsigned kFrameTailBits = 10;
// Intermission between two frames; counted with the frame because the bus cannot carry another one.
inline constexpr unsigned kIntermissionBits = 3;
// An error frame as SocketCAN reports it: 6-bit error flag + 8-bit delimiter + intermission. The bits
// of the frame it destroyed are not known, so this is the minimum (the same count VirtualBus uses).
inline constexpr unsigned kErrorFrameBits = 6 + 8 + kIntermissionBits;

// Bit times the frame occupies on the wire: SOF through CRC sequence with the stuff bits (a
// complementary bit after every 5 equal bits, stuff bits counting toward the next run; a stuff bit
// after the last CRC bit included), then the fixed-form tail and the intermission. The CRC is the real
// CRC-15 (0x4599) over the destuffed SOF..data bits. Standard and extended (29-bit) data and remote
// frames; a remote frame sends len as its DLC and no data field. len above 8 counts as 8 (Frame never
// carries more). Error frames count kErrorFrameBits.
unsigned frameBits(const Frame& f);

// Bus load from the frames seen: add() each frame, then load() over the time they were collected in.
// Cheap enough for the per-frame path: no allocation, no exception, a few hundred bit steps per frame.
class BusLoadMeter {
 public:
  void add(const Frame& f) {
    bits_ += frameBits(f);
    ++frames_;
  }
  std::uint64_t bits() const { return bits_; }
  std::uint64_t frames() const { return frames_; }
  // Fraction of the bus capacity used: bits / (seconds * bitrate); 0 for an empty window (no time or
  // no bitrate) rather than a division by zero.
  double load(double seconds, std::uint32_t bitrate) const {
    const double capacity = seconds * static_cast<double>(bitrate);
    return capacity > 0.0 ? static_cast<double>(bits_) / capacity : 0.0;
  }
  void reset() {
    bits_ = 0;
    frames_ = 0;
  }

 private:
  std::uint64_t bits_ = 0;
  std::uint64_t frames_ = 0;
};

}  // namespace pamc::canopen
