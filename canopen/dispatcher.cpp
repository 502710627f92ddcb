#include "canopen/dispatcher.hpp"

namespace pamc::canopen {

bool Dispatcher::subscribe(std::uint32_t cob_id, Handler fn, void* ctx) {
  if (cob_id > kStandardIdMask || fn == nullptr) return false;
  Slot& s = table_[cob_id];
  if (s.fn != nullptr && s.ctx != ctx) return false;
  s.fn = fn;
  s.ctx = ctx;
  return true;
}

void Dispatcher::unsubscribe(std::uint32_t cob_id, void* ctx) {
  if (cob_id > kStandardIdMask) return;
  Slot& s = table_[cob_id];
  if (s.ctx == ctx) s = Slot{};
}

bool Dispatcher::dispatch(const Frame& frame, TimeUs now) const {
  if (frame.extended() || frame.id > kStandardIdMask) return false;
  const Slot& s = table_[frame.id];
  if (s.fn == nullptr) return false;
  s.fn(s.ctx, frame, now);
  return true;
}

}  // namespace pamc::canopen
