// SDO client (CiA 301, 7.2.4): one non-blocking transfer at a time; completion via callback.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <type_traits>
#include <vector>

#include "canopen/service.hpp"

namespace pamc::canopen {

class SdoClient {
 public:
  // abort_code is kSdoOk on success; data/len hold the uploaded value (empty for a download).
  using Callback = std::function<void(std::uint32_t abort_code, const std::uint8_t* data, std::size_t len)>;

  SdoClient(NodeContext& ctx, TimeUs timeout_us, std::size_t buffer_size);

  // Starts a download (write) to server_node's default SDO (0x600+id / 0x580+id). Expedited up to 4 bytes,
  // segmented above. Returns false if a transfer is running or the data does not fit the buffer.
  bool download(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, const std::uint8_t* data,
                std::size_t len, Callback done);
  template <class T>
  bool downloadValue(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, T value, Callback done) {
    static_assert(std::is_arithmetic_v<T>, "downloadValue needs an arithmetic type");
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &value, sizeof(T));
    return download(server_node, index, sub, b, sizeof(T), std::move(done));
  }
  // Starts an upload (read).
  bool upload(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, Callback done);
  // Aborts the running transfer (sends the abort frame, callback gets code).
  void abort(std::uint32_t code);
  bool busy() const { return state_ != State::Idle; }

  void onFrame(const Frame& f, TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const { return state_ == State::Idle ? kNever : deadline_us_; }

 private:
  enum class State : std::uint8_t { Idle, DownloadInitiate, DownloadSegment, UploadInitiate, UploadSegment };
  bool begin(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, Callback done, State state);
  void request(const std::uint8_t (&data)[8]);
  void sendSegment();
  void finish(std::uint32_t code, const std::uint8_t* data, std::size_t len);
  void fail(std::uint32_t code);  // sends an abort frame and finishes

  NodeContext& ctx_;
  TimeUs timeout_us_;
  std::vector<std::uint8_t> buffer_;  // sized once
  State state_ = State::Idle;
  Callback done_;
  std::uint32_t tx_id_ = 0;
  std::uint32_t rx_id_ = 0;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::uint8_t toggle_ = 0;
  bool size_indicated_ = false;
  std::size_t size_ = 0;
  std::size_t offset_ = 0;
  bool last_sent_ = false;
  TimeUs deadline_us_ = kNever;
};

}  // namespace pamc::canopen
