// CAN frame and time types shared by every part of the CANopen layer.
#pragma once

#include <cstdint>
#include <cstring>
#include <limits>

namespace pamc::canopen {

// Microseconds on the node's clock (monotonic, arbitrary epoch); the core never reads a clock itself.
using TimeUs = std::int64_t;
inline constexpr TimeUs kNever = std::numeric_limits<TimeUs>::max();

// Frame::flags bits.
inline constexpr std::uint8_t kFrameExtended = 0x01;  // 29-bit identifier
inline constexpr std::uint8_t kFrameRemote = 0x02;    // RTR frame
inline constexpr std::uint8_t kFrameError = 0x04;     // SocketCAN error frame; id holds the error class bits

inline constexpr std::uint32_t kStandardIdMask = 0x7FF;
inline constexpr std::uint32_t kExtendedIdMask = 0x1FFFFFFF;

// Fixed-size classic CAN frame: copied by value, never allocated.
struct Frame {
  std::uint32_t id = 0;
  std::uint8_t len = 0;
  std::uint8_t data[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  std::uint8_t flags = 0;

  bool extended() const { return (flags & kFrameExtended) != 0; }
  bool remote() const { return (flags & kFrameRemote) != 0; }
  bool error() const { return (flags & kFrameError) != 0; }
};

inline bool operator==(const Frame& a, const Frame& b) {
  return a.id == b.id && a.len == b.len && a.flags == b.flags &&
         std::memcmp(a.data, b.data, a.len <= 8 ? a.len : 8) == 0;
}
inline bool operator!=(const Frame& a, const Frame& b) { return !(a == b); }

// CiA 301 (7.3.5) restricted CAN-IDs: NMT, the default SDO and NMT error control identifiers and the
// reserved ranges. No configurable communication object (SYNC, EMCY, PDO) may be set to one.
inline bool restrictedCobId(std::uint32_t id) {
  return id <= 0x07F || (id >= 0x101 && id <= 0x180) || (id >= 0x581 && id <= 0x5FF) || (id >= 0x601 && id <= 0x67F) ||
         (id >= 0x6E0 && id <= 0x6FF) || (id >= 0x701 && id <= 0x7FF);
}

// Builds a standard data frame; bytes beyond len stay zero.
inline Frame makeFrame(std::uint32_t id, std::uint8_t len, const std::uint8_t* bytes = nullptr) {
  Frame f;
  f.id = id;
  f.len = len > 8 ? 8 : len;
  if (bytes != nullptr) std::memcpy(f.data, bytes, f.len);
  return f;
}

// Little-endian helpers: CANopen puts every multi-byte value on the wire LSB first.
inline std::uint16_t getU16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
inline std::uint32_t getU32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}
inline void putU16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
inline void putU32(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
  p[2] = static_cast<std::uint8_t>(v >> 16);
  p[3] = static_cast<std::uint8_t>(v >> 24);
}

}  // namespace pamc::canopen
