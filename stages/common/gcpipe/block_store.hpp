// The program as the later phases read it: its blocks in order, held where they do not add to
// the process's memory (issue 12: a one-hour CAM program is 48,000 blocks of 472 bytes, 22 MB,
// and a std::vector collecting them peaked at 1.5-2x that while it grew and was shrunk).
#pragma once

#include <cstddef>
#include <new>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

#include "gcpipe/block.hpp"
#include "gcpipe/scratch.hpp"

namespace gcpipe {

/// Blocks in a scratch file's pages (gcpipe/scratch.hpp), in address space reserved for
/// `max_blocks` up front: a block holds std::strings, which cannot be moved bitwise, so the
/// blocks are never moved at all; no growth copies them and no spare room is left to give back.
/// What stays in the process per block is only its strings' heap (long source lines). Beside the
/// blocks the store keeps their briefs (BlockBrief, 32 bytes): the passes over the whole program
/// read those, so that they do not map the blocks' pages faster than they can be dropped.
class BlockStore {
 public:
  explicit BlockStore(std::size_t max_blocks = 0) : max_(max_blocks) {}
  BlockStore(const BlockStore& o) : max_(o.max_) {
    for (const ResolvedBlock& b : o) push_back(b);
  }
  BlockStore& operator=(const BlockStore& o) {
    if (this != &o) *this = BlockStore(o);
    return *this;
  }
  BlockStore(BlockStore&& o) noexcept
      : bytes_(std::move(o.bytes_)), briefs_(std::move(o.briefs_)), size_(std::exchange(o.size_, 0)), max_(o.max_) {}
  BlockStore& operator=(BlockStore&& o) noexcept {
    if (this != &o) {
      clear();
      bytes_ = std::move(o.bytes_);
      briefs_ = std::move(o.briefs_);
      size_ = std::exchange(o.size_, 0);
      max_ = o.max_;
    }
    return *this;
  }
  ~BlockStore() { clear(); }

  /// Throws std::length_error past max_blocks (the caller bounds the program before).
  void push_back(const ResolvedBlock& b) { add(*new (room()) ResolvedBlock(b)); }
  void push_back(ResolvedBlock&& b) { add(*new (room()) ResolvedBlock(std::move(b))); }
  /// The blocks destroyed and their memory given back. Destroying a block reads it (its strings),
  /// so the pages are dropped behind as it goes: destroying a whole program at once mapped all
  /// of its pages in milliseconds, which was the peak of a long run's memory (22 MB at the end of
  /// the one-hour program).
  void clear() {
    constexpr std::size_t kDropEvery = (std::size_t{1} << 20) / sizeof(ResolvedBlock);
    for (std::size_t i = 0; i < size_; ++i) {
      data()[i].~ResolvedBlock();
      if ((i + 1) % kDropEvery == 0) bytes_.discard_before((i + 1) * sizeof(ResolvedBlock));
    }
    size_ = 0;
    bytes_.release();
    briefs_.release();
  }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  std::size_t max_size() const { return max_; }
  const ResolvedBlock* data() const {
    return bytes_.data() ? std::launder(reinterpret_cast<const ResolvedBlock*>(bytes_.data())) : nullptr;
  }
  ResolvedBlock* data() { return bytes_.data() ? std::launder(reinterpret_cast<ResolvedBlock*>(bytes_.data())) : nullptr; }
  const ResolvedBlock& operator[](std::size_t i) const { return data()[i]; }
  const ResolvedBlock& front() const { return data()[0]; }
  const ResolvedBlock& back() const { return data()[size_ - 1]; }
  const ResolvedBlock* begin() const { return data(); }
  const ResolvedBlock* end() const { return data() + size_; }
  std::span<const ResolvedBlock> span() const { return {data(), size_}; }
  operator std::span<const ResolvedBlock>() const { return span(); }
  std::span<const BlockBrief> briefs() const { return {briefs_.data(), briefs_.size()}; }

 private:
  void* room() {
    if (size_ >= max_) throw std::length_error("more than " + std::to_string(max_) + " blocks");
    if (!bytes_.data()) bytes_.reserve_address(max_ * sizeof(ResolvedBlock));
    bytes_.back((size_ + 1) * sizeof(ResolvedBlock));
    return bytes_.data() + size_ * sizeof(ResolvedBlock);
  }
  // The block just made at room(): counted once its brief is kept too (a full scratch disk
  // throws there, and the block is undone).
  void add(ResolvedBlock& b) {
    try {
      briefs_.push_back(brief_of(b));
    } catch (...) {
      b.~ResolvedBlock();
      throw;
    }
    ++size_;
  }
  ScratchBytes bytes_;
  ScratchArray<BlockBrief> briefs_;
  std::size_t size_ = 0;
  std::size_t max_;
};

}  // namespace gcpipe
