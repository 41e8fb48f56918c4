/// @file allocation_counter.h
/// Counts every operator new of the test executable, so that a test can assert that a step
/// allocates nothing. It replaces the global operator new and delete: include it in exactly one
/// translation unit of an executable (each core test is one).
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> gAllocations{0};
}  // namespace

// Kept out of line: inlined, GCC mistakes this malloc/free pair for a new/free mismatch.
__attribute__((noinline)) void* operator new(std::size_t size) {
  ++gAllocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
__attribute__((noinline)) void operator delete(void* p) noexcept { std::free(p); }
__attribute__((noinline)) void operator delete(void* p, std::size_t) noexcept { std::free(p); }
