// EMCY (CiA 301, 7.2.7): producer (COB-ID 0x1014, inhibit 0x1015, error register 0x1001,
// history 0x1003) and consumer of other nodes' emergencies.
#pragma once

#include <array>
#include <cstdint>
#include <functional>

#include "canopen/service.hpp"

namespace pamc::canopen {

inline constexpr std::uint32_t kEmcyCobIdBase = 0x080;

// Error register (0x1001) bits.
inline constexpr std::uint8_t kErrRegGeneric = 0x01;
inline constexpr std::uint8_t kErrRegCurrent = 0x02;
inline constexpr std::uint8_t kErrRegVoltage = 0x04;
inline constexpr std::uint8_t kErrRegTemperature = 0x08;
inline constexpr std::uint8_t kErrRegCommunication = 0x10;
inline constexpr std::uint8_t kErrRegDeviceProfile = 0x20;
inline constexpr std::uint8_t kErrRegManufacturer = 0x80;

// A few error codes (CiA 301, table 21) used in this project.
inline constexpr std::uint16_t kEmcyNoError = 0x0000;
inline constexpr std::uint16_t kEmcyGeneric = 0x1000;
inline constexpr std::uint16_t kEmcyCommunication = 0x8100;
inline constexpr std::uint16_t kEmcyCanOverrun = 0x8110;
inline constexpr std::uint16_t kEmcyErrorPassive = 0x8120;
inline constexpr std::uint16_t kEmcyHeartbeat = 0x8130;
inline constexpr std::uint16_t kEmcyBusOffRecovered = 0x8140;
inline constexpr std::uint16_t kEmcyCanIdCollision = 0x8150;
inline constexpr std::uint16_t kEmcyPdoLength = 0x8210;
inline constexpr std::uint16_t kEmcySyncLength = 0x8240;
inline constexpr std::uint16_t kEmcyRpdoTimeout = 0x8250;
inline constexpr std::uint16_t kEmcySoftware = 0x6100;
inline constexpr std::uint16_t kEmcyDataSet = 0x6300;      // software: data set (a slave's configuration)
inline constexpr std::uint16_t kEmcySensor = 0x7300;       // additional modules: sensor
inline constexpr std::uint16_t kEmcySensorRange = 0x7310;  // sensor: value outside its measuring range
inline constexpr std::uint16_t kEmcyDeviceSpecific = 0xFF00;

struct EmcyMessage {
  std::uint8_t node_id = 0;
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::uint8_t manufacturer[5] = {};
};

// Error register bit of an error code's class (besides the generic bit that is set for every error).
std::uint8_t errorRegisterBit(std::uint16_t error_code);

class Emcy {
 public:
  using ConsumerHook = std::function<void(const EmcyMessage& msg, TimeUs now)>;

  explicit Emcy(NodeContext& ctx) : ctx_(ctx) {}
  void setConsumerHook(ConsumerHook h) { hook_ = std::move(h); }
  void registerHooks();
  // Reads 0x1014/0x1015 and subscribes the consumer (0x1028 if present, else 0x81..0xFF except this node).
  void configure();

  // An error occurred: sets the error register, records 0x1003, sends the EMCY frame. source tells
  // apart the same error of several parts of a device (a controller's channels): each is active by
  // itself. Returns false if the error was already active or the frame could not be queued.
  bool report(std::uint16_t error_code, const std::uint8_t* manufacturer = nullptr, std::uint8_t source = 0);
  // The error disappeared: updates the register and sends an "error reset" EMCY (code 0x0000), with
  // manufacturer's bytes if given.
  bool clear(std::uint16_t error_code, std::uint8_t source = 0, const std::uint8_t* manufacturer = nullptr);
  void clearAll();
  bool active(std::uint16_t error_code) const;
  std::uint8_t errorRegister() const { return register_; }
  // The COB-ID this node sends its EMCY on (0x1014), and whether it is enabled.
  std::uint32_t cobId() const { return cob_id_; }
  bool enabled() const { return enabled_; }

  void onFrame(const Frame& f, TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const;

 private:
  static constexpr std::size_t kMaxActive = 16;
  // Room for an error reset per code and channel of 8 channels, spaced by the inhibit time.
  static constexpr std::size_t kQueue = 32;
  void updateRegister();
  bool queue(std::uint16_t code, const std::uint8_t* manufacturer);
  void flushQueue(TimeUs now);

  NodeContext& ctx_;
  ConsumerHook hook_;
  std::uint32_t cob_id_ = 0;
  bool enabled_ = false;
  TimeUs inhibit_us_ = 0;
  bool has_sent_ = false;
  TimeUs last_tx_us_ = 0;
  bool activeFrom(std::uint32_t key) const;
  std::array<std::uint32_t, kMaxActive> active_{};  // error code | source << 16
  std::size_t active_count_ = 0;
  std::uint8_t register_ = 0;
  std::array<Frame, kQueue> queue_{};
  std::size_t queue_head_ = 0;
  std::size_t queue_count_ = 0;
};

}  // namespace pamc::canopen
