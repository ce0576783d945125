// Storage for the long per-tick series of a run (issue 12: memory that does not grow with the
// program). A one-hour program's raw samples, planned reference and their indices are 4-5 M ticks
// each; held in the process they made memory grow 0.05 MB a machine-second. Past kSpillBytes an
// array lives in an unlinked scratch file mapped into the process instead: its pages are written
// to the kernel's page cache (and to disk, reclaimable under memory pressure), and the pages the
// process has not touched in the last trim period are dropped from its resident set, to fault
// back in from the page cache if read again. Every series is read front to back by each phase,
// so what is resident is what the phases touch in a period, whatever the program's length.
// The values are the same bytes either way: no result depends on where a series is kept.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <initializer_list>
#include <iterator>
#include <string>
#include <type_traits>
#include <utility>

namespace gcpipe {

/// Raw bytes that grow without copying: anonymous memory while below kSpillBytes, then an
/// unlinked file in the scratch directory (scratch_directory()) mapped shared.
class ScratchBytes {
 public:
  static constexpr std::size_t kSpillBytes = std::size_t{1} << 20;

  ScratchBytes() = default;
  ScratchBytes(const ScratchBytes&) = delete;
  ScratchBytes& operator=(const ScratchBytes&) = delete;
  ScratchBytes(ScratchBytes&& o) noexcept { swap(o); }
  ScratchBytes& operator=(ScratchBytes&& o) noexcept {
    if (this != &o) {
      release();
      swap(o);
    }
    return *this;
  }
  ~ScratchBytes() { release(); }

  std::byte* data() const { return data_; }
  std::size_t capacity() const { return capacity_; }
  bool spilled() const { return fd_ >= 0; }
  /// Capacity at least `bytes`, the contents kept (the mapping moves: pointers into it do not survive).
  void grow(std::size_t bytes);
  /// For values that cannot be moved bitwise (std::string points into itself): `bytes` of address
  /// space that never moves, a scratch file's (any size) or else memory; call before anything else.
  /// Disk is taken as the values reach it (back()).
  void reserve_address(std::size_t bytes);
  /// The first `bytes` of a reserved address range can be written (disk taken for them).
  void back(std::size_t bytes);
  /// Capacity about `bytes` (>= it), the contents below it kept: gives back what a series did not use.
  void shrink(std::size_t bytes);
  /// The bytes of whole pages in [0, bytes) are no longer needed: their memory (and disk) is freed
  /// and they read as zeros from here on.
  void discard_before(std::size_t bytes);
  void release();
  void swap(ScratchBytes& o) noexcept {
    std::swap(data_, o.data_);
    std::swap(capacity_, o.capacity_);
    std::swap(fd_, o.fd_);
    std::swap(backed_, o.backed_);
  }

 private:
  void map_anonymous(std::size_t bytes);
  void move_to_file(std::size_t bytes);
  std::byte* data_ = nullptr;
  std::size_t capacity_ = 0;  // bytes mapped
  int fd_ = -1;               // the scratch file once spilled
  std::size_t backed_ = 0;    // reserve_address(): bytes with disk under them
};

/// For a pass that maps scratch pages at gigabytes a second (a field or two read per element, or
/// a series converted whole), faster than the trimmer thread's 5 ms poll follows: call it every
/// megabyte or so. When the resident set has grown 8 MB since the last trim, the spilled pages are
/// dropped now (a syscall to read the size; the trim itself when due).
void trim_scratch_if_grown();

/// Where spilled series go: $GCPIPE_SCRATCH_DIR, else /var/tmp (on disk by the FHS; /tmp is often
/// a tmpfs, which would hold the pages in memory again).
std::string scratch_directory();

/// A std::vector-like array of trivially copyable values in ScratchBytes. Growth never copies the
/// values (the mapping is moved), so no reservation is needed to avoid a doubling peak.
template <class T>
class ScratchArray {
  static_assert(std::is_trivially_copyable_v<T>, "a scratch array holds plain values");

 public:
  using value_type = T;
  ScratchArray() = default;
  ScratchArray(std::initializer_list<T> values) { assign(values.begin(), values.end()); }
  ScratchArray(const ScratchArray& o) { assign(o.begin(), o.end()); }
  ScratchArray& operator=(const ScratchArray& o) {
    if (this != &o) assign(o.begin(), o.end());
    return *this;
  }
  ScratchArray(ScratchArray&& o) noexcept : bytes_(std::move(o.bytes_)), size_(std::exchange(o.size_, 0)) {}
  ScratchArray& operator=(ScratchArray&& o) noexcept {
    bytes_ = std::move(o.bytes_);
    size_ = std::exchange(o.size_, 0);
    return *this;
  }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  std::size_t capacity() const { return bytes_.capacity() / sizeof(T); }
  T* data() { return reinterpret_cast<T*>(bytes_.data()); }
  const T* data() const { return reinterpret_cast<const T*>(bytes_.data()); }
  T* begin() { return data(); }
  T* end() { return data() + size_; }
  const T* begin() const { return data(); }
  const T* end() const { return data() + size_; }
  T& operator[](std::size_t i) { return data()[i]; }
  const T& operator[](std::size_t i) const { return data()[i]; }
  T& front() { return data()[0]; }
  const T& front() const { return data()[0]; }
  T& back() { return data()[size_ - 1]; }
  const T& back() const { return data()[size_ - 1]; }

  void reserve(std::size_t n) {
    if (n > capacity()) bytes_.grow(n * sizeof(T));
  }
  void push_back(const T& x) {
    if (size_ == capacity()) {
      const T copy = x;  // x may live in this array
      bytes_.grow(std::max<std::size_t>(2 * size_, 1024) * sizeof(T));
      data()[size_++] = copy;
      return;
    }
    data()[size_++] = x;
  }
  /// New values are value-initialised (as std::vector's).
  void resize(std::size_t n, const T& value = T{}) {
    reserve(n);
    for (std::size_t i = size_; i < n; ++i) data()[i] = value;
    size_ = n;
  }
  void assign(std::size_t n, const T& value) {
    size_ = 0;
    resize(n, value);
  }
  template <class It>
  void assign(It first, It last) {
    size_ = 0;
    reserve(static_cast<std::size_t>(std::distance(first, last)));
    for (; first != last; ++first) data()[size_++] = *first;
  }
  void clear() { size_ = 0; }
  void shrink_to_fit() { bytes_.shrink(size_ * sizeof(T)); }
  /// Gives the memory back (clear() keeps it).
  void release() {
    bytes_.release();
    size_ = 0;
  }
  /// Values before `n` are no longer read: the whole pages under them are freed.
  void discard_before(std::size_t n) { bytes_.discard_before(n * sizeof(T)); }
  bool operator==(const ScratchArray& o) const {
    return size_ == o.size_ && (size_ == 0 || std::memcmp(data(), o.data(), size_ * sizeof(T)) == 0);
  }

 private:
  ScratchBytes bytes_;
  std::size_t size_ = 0;
};

}  // namespace gcpipe
