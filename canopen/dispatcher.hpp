// Routes received frames to the service that owns their COB-ID (11-bit identifiers, table lookup).
#pragma once

#include <array>
#include <cstdint>

#include "canopen/frame.hpp"

namespace pamc::canopen {

class Dispatcher {
 public:
  // Plain function pointer + context: calling it never allocates.
  using Handler = void (*)(void* ctx, const Frame& frame, TimeUs now);

  // Returns false if the COB-ID is out of range or owned by another handler.
  bool subscribe(std::uint32_t cob_id, Handler fn, void* ctx);
  // Removes the subscription if ctx owns it.
  void unsubscribe(std::uint32_t cob_id, void* ctx);
  bool subscribed(std::uint32_t cob_id) const { return cob_id <= kStandardIdMask && table_[cob_id].fn != nullptr; }
  // True if ctx could subscribe cob_id (free, or already its own).
  bool available(std::uint32_t cob_id, const void* ctx) const {
    return cob_id <= kStandardIdMask && (table_[cob_id].fn == nullptr || table_[cob_id].ctx == ctx);
  }
  // Calls the handler; false if no service listens to this COB-ID (the caller counts it).
  bool dispatch(const Frame& frame, TimeUs now) const;

  // Subscribes a member function: dispatcher.subscribe<&Sync::onFrame>(0x80, this).
  template <auto Method, class T>
  bool subscribe(std::uint32_t cob_id, T* obj) {
    return subscribe(
        cob_id, [](void* ctx, const Frame& f, TimeUs now) { (static_cast<T*>(ctx)->*Method)(f, now); }, obj);
  }

 private:
  struct Slot {
    Handler fn = nullptr;
    void* ctx = nullptr;
  };
  std::array<Slot, kStandardIdMask + 1> table_{};
};

}  // namespace pamc::canopen
