// SDO server (CiA 301, 7.2.4): expedited and segmented upload/download with toggle bit and timeout.
#pragma once

#include <cstdint>
#include <vector>

#include "canopen/service.hpp"

namespace pamc::canopen {

inline constexpr std::uint32_t kSdoRequestBase = 0x600;   // client -> server
inline constexpr std::uint32_t kSdoResponseBase = 0x580;  // server -> client

class SdoServer {
 public:
  SdoServer(NodeContext& ctx, TimeUs timeout_us) : ctx_(ctx), timeout_us_(timeout_us) {}
  // Sizes the transfer buffer for the largest entry and subscribes the request COB-ID
  // (0x1200 if the OD has it, else 0x600 + node-ID). Configuration time.
  void configure();
  void onFrame(const Frame& f, TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const;
  // Drops a transfer in progress without a frame (NMT reset).
  void reset() { state_ = State::Idle; }

  std::uint32_t requestCobId() const { return rx_id_; }
  std::uint32_t responseCobId() const { return tx_id_; }
  bool busy() const { return state_ != State::Idle; }

 private:
  enum class State : std::uint8_t { Idle, Download, Upload };
  void initiateDownload(const Frame& f, TimeUs now);
  void initiateUpload(const Frame& f, TimeUs now);
  void downloadSegment(const Frame& f, TimeUs now);
  void uploadSegment(const Frame& f, TimeUs now);
  // Resolves index/sub of a request; returns the abort code if the entry does not exist.
  std::uint32_t lookup(std::uint16_t index, std::uint8_t sub);
  void respond(const std::uint8_t (&data)[8]);
  void abort(std::uint16_t index, std::uint8_t sub, std::uint32_t code);

  NodeContext& ctx_;
  TimeUs timeout_us_;
  std::uint32_t rx_id_ = 0;
  std::uint32_t tx_id_ = 0;
  bool subscribed_ = false;
  State state_ = State::Idle;
  Entry* entry_ = nullptr;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::uint8_t toggle_ = 0;
  bool size_indicated_ = false;
  std::size_t size_ = 0;    // indicated (download) or total (upload) size
  std::size_t offset_ = 0;  // bytes transferred so far
  TimeUs deadline_us_ = kNever;
  std::vector<std::uint8_t> buffer_;  // sized once in configure()
};

}  // namespace pamc::canopen
