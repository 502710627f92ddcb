#include "nodes/fault_supervisor.hpp"

namespace pamc::nodes {

using canopen::TimeUs;

namespace {
constexpr std::uint32_t bit(Fault f) { return faultBit(f); }
constexpr std::uint32_t kWarnMask = warningMask();
constexpr std::uint32_t kSafetyMask = ((1u << kFaultCount) - 2u) & ~kWarnMask;
// The causes of the bus, met by every channel at once.
constexpr std::uint32_t kBusMask = bit(Fault::BusError) | bit(Fault::SyncLost) | bit(Fault::CanOverrun) |
                                   bit(Fault::BusOff) | bit(Fault::IdCollision) | bit(Fault::PdoLength) |
                                   bit(Fault::SyncLength);
}  // namespace

// An error reset names the channel too (byte 3, as in the EMCY it resets).
const std::uint8_t* FaultSupervisor::resetBytes() noexcept {
  reset_bytes_[2] = channel_;
  return reset_bytes_;
}

bool FaultSupervisor::reports(Fault f) const noexcept { return reports_bus_ || (kBusMask & bit(f)) == 0; }

void FaultSupervisor::raise(Fault f, std::uint8_t detail) noexcept {
  pending_ |= bit(f);
  detail_[static_cast<unsigned>(f)] = detail;
}

bool FaultSupervisor::takeCauses(TimeUs now) noexcept {
  const std::uint32_t p = pending_;
  pending_ = 0;
  if (p == 0) return false;
  if (reacted_at_us_ == canopen::kNever) reacted_at_us_ = now;
  for (int i = 1; i < kFaultCount; ++i) {
    const auto f = static_cast<Fault>(i);
    if ((p & bit(f)) == 0 || (episode_ & bit(f)) != 0) continue;
    if (f == Fault::BusOff) continue;  // nothing goes out in bus off: its EMCY (0x8140) follows the restart
    episode_ |= bit(f);
    if (!reports(f)) continue;
    const std::uint8_t m[5] = {static_cast<std::uint8_t>(i), detail_[i], channel_, 0, 0};
    node_.emcy().report(emcyCode(f), m, channel_);
    if (isWarning(f)) ++counters_.warnings;
  }
  if ((p & kWarnMask) != 0) warn_clear_ = 0;
  if ((p & kSafetyMask) == 0) return false;
  clear_cycles_ = 0;
  if ((p & kSafetyMask & ~bit(Fault::OtherChannel)) != 0) own_clear_cycles_ = 0;
  if (fault_ != Fault::None) return false;
  for (int i = 1; i < kFaultCount; ++i)
    if ((p & kSafetyMask & bit(static_cast<Fault>(i))) != 0) {
      fault_ = static_cast<Fault>(i);
      break;
    }
  ++raised_;
  ++counters_.episodes;
  publish();
  return true;
}

void FaultSupervisor::recover() noexcept {
  for (int i = 1; i < kFaultCount; ++i) {
    const auto f = static_cast<Fault>(i);
    if ((episode_ & kSafetyMask & bit(f)) != 0 && reports(f)) node_.emcy().clear(emcyCode(f), channel_, resetBytes());
  }
  episode_ &= kWarnMask;
  if (episode_ == 0) reacted_at_us_ = canopen::kNever;
  fault_ = Fault::None;
  ++counters_.recoveries;
}

void FaultSupervisor::clearWarnings() noexcept {
  if ((episode_ & kWarnMask) == 0 || ++warn_clear_ < recover_cycles_) return;
  for (int i = 1; i < kFaultCount; ++i) {
    const auto w = static_cast<Fault>(i);
    if (isWarning(w) && (episode_ & bit(w)) != 0 && reports(w)) node_.emcy().clear(emcyCode(w), channel_, resetBytes());
  }
  episode_ &= ~kWarnMask;
  if (fault_ == Fault::None) reacted_at_us_ = canopen::kNever;
}

void FaultSupervisor::pollBus() noexcept {
  // Frames this node could not send (transmit queue full, ENOBUFS beyond the queue): overrun.
  const auto& c = node_.counters();
  if (c.tx_dropped != bus_.tx_dropped) {
    bus_.tx_dropped = c.tx_dropped;
    raise(Fault::CanOverrun);
  }
  // Frames that missed their deadline, or more than two cycles of frames waiting: this node's frames
  // are not getting onto the bus.
  if (node_.txExpired() != bus_.tx_expired) {
    bus_.tx_expired = node_.txExpired();
    raise(Fault::CanOverrun);
  }
  if (node_.txBacklog() > 4) raise(Fault::CanOverrun);
  if (c.rpdo_wrong_length != bus_.pdo_length) {
    bus_.pdo_length = c.rpdo_wrong_length;
    raise(Fault::PdoLength);
  }
  if (node_.sync().wrongLength() != bus_.sync_length) {
    bus_.sync_length = node_.sync().wrongLength();
    raise(Fault::SyncLength);
  }
  if (bus_.off) raise(Fault::BusOff);
}

void FaultSupervisor::onErrorFrame(const canopen::Frame& f) noexcept {
  // Linux error-frame classes (linux/can/error.h): controller problem 0x04 (data[1]: 0x01/0x02 rx/tx
  // overflow, 0x10/0x20 rx/tx error passive), bus off 0x40, restarted after bus off 0x100.
  const bool crtl = (f.id & 0x04u) != 0;
  if ((f.id & 0x40u) != 0) {
    bus_.off = true;
    raise(Fault::BusOff);
  }
  if ((f.id & 0x100u) != 0 && bus_.off) {
    bus_.off = false;
    // Back on the bus: now the EMCY can go out.
    const std::uint8_t m[5] = {static_cast<std::uint8_t>(Fault::BusOff), 0, channel_, 0, 0};
    if (reports_bus_) node_.emcy().report(emcyCode(Fault::BusOff), m, channel_);
    episode_ |= bit(Fault::BusOff);
  }
  if (crtl && (f.data[1] & 0x30u) != 0) raise(Fault::BusError);
  if (crtl && (f.data[1] & 0x03u) != 0) raise(Fault::CanOverrun);
}

}  // namespace pamc::nodes
