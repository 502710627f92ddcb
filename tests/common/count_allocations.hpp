// Counts the heap allocations a test asks about (the 1 kHz cycle must allocate nothing): it replaces the
// test program's global operator new and delete, so include it in exactly one source file per program.
// Off under AddressSanitizer, which owns operator new (PAMC_COUNT_ALLOCATIONS is 0 there).
#pragma once

// The replaced operator new/delete below pair malloc with free; GCC's inliner sees the library's
// operator new next to this file's delete and warns of a mismatch that is not there.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

#include <atomic>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define PAMC_COUNT_ALLOCATIONS 0
#else
#define PAMC_COUNT_ALLOCATIONS 1
#endif

namespace pamc::test {
inline std::atomic<long> g_allocs{0};
inline thread_local bool g_counting = false;

// Counts this thread's allocations from construction to destruction.
struct CountAllocations {
  CountAllocations() {
    g_allocs = 0;
    g_counting = true;
  }
  ~CountAllocations() { g_counting = false; }
  CountAllocations(const CountAllocations&) = delete;
  CountAllocations& operator=(const CountAllocations&) = delete;
  long count() const { return g_allocs.load(); }
};
}  // namespace pamc::test

#if PAMC_COUNT_ALLOCATIONS
void* operator new(std::size_t n) {
  if (pamc::test::g_counting) ++pamc::test::g_allocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (pamc::test::g_counting) ++pamc::test::g_allocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
// Over-aligned types (Eigen's fixed-size matrices with alignas) come through these.
void* operator new(std::size_t n, std::align_val_t a) {
  if (pamc::test::g_counting) ++pamc::test::g_allocs;
  const std::size_t al = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(al, (n + al - 1) / al * al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
#endif
