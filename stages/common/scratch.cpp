#include "gcpipe/scratch.hpp"

#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <new>
#include <stdexcept>
#include <thread>

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace gcpipe {
namespace {

std::size_t page_size() {
  static const std::size_t n = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  return n;
}

std::size_t whole_pages(std::size_t bytes) { return (bytes + page_size() - 1) / page_size() * page_size(); }

/// Pages resident in the process now (/proc/self/statm's second field), 0 if unknown. The file is
/// kept open and read again from its start: the trimmer asks every few milliseconds.
std::size_t resident_pages() {
  static const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  char text[128];
  const ssize_t n = fd < 0 ? -1 : ::pread(fd, text, sizeof text - 1, 0);
  if (n <= 0) return 0;
  text[n] = '\0';
  unsigned long size = 0, resident = 0;
  return std::sscanf(text, "%lu %lu", &size, &resident) == 2 ? resident : 0;
}

/// Drops the spilled mappings' pages from the resident set. A page still in use faults back in
/// from the page cache (a minor fault; a read fault maps 16 pages at a time), so this costs a
/// little time and no value. It is done when the process's resident set has grown by kGrowth
/// since the last time and every kPeriod anyway. A pass that computes on every tick touches at
/// most hundreds of MB a second, so it stays within a few MB of kGrowth; a pass that reads a field
/// or two per element maps the page cache at gigabytes a second (a whole program's blocks between
/// two polls, measured), which no polling follows: such passes read the blocks' briefs instead
/// (BlockBrief) or call trim_scratch_if_grown() as they go. A thread, because the readers of a
/// series are many loops in several stages, and a series read again (the read-back, the figures)
/// would otherwise stay resident to the end.
class ResidentSetTrimmer {
 public:
  static constexpr std::chrono::milliseconds kPoll{5};
  static constexpr std::chrono::milliseconds kPeriod{200};
  static constexpr std::size_t kGrowth = std::size_t{8} << 20;

  void add(std::byte* p, std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    regions_[p] = bytes;
    if (!thread_.joinable()) thread_ = std::thread([this] { run(); });
    wake_.notify_one();
  }
  /// After this the region is never touched again: the caller may unmap it.
  void remove(std::byte* p) {
    std::lock_guard<std::mutex> lock(mutex_);
    regions_.erase(p);
  }
  /// The trim, now, if the resident set has grown by kGrowth since the last: for a pass that maps
  /// scratch pages faster than the thread's poll follows.
  void trim_if_grown() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!regions_.empty() && resident_pages() >= after_trim_ + kGrowth / page_size()) trim();
  }
  ~ResidentSetTrimmer() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void run() {
    const std::size_t growth_pages = kGrowth / page_size();
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      if (regions_.empty()) wake_.wait(lock, [this] { return stop_ || !regions_.empty(); });
      else wake_.wait_for(lock, kPoll, [this] { return stop_; });
      if (resident_pages() < after_trim_ + growth_pages && std::chrono::steady_clock::now() - last_ < kPeriod) continue;
      trim();
    }
  }
  // Under the lock: a region removed (and then unmapped, its addresses perhaps reused) is never
  // advised. MADV_DONTNEED on a shared file mapping keeps the contents (the file has them).
  void trim() {
    for (const auto& [p, bytes] : regions_) ::madvise(p, bytes, MADV_DONTNEED);
    after_trim_ = resident_pages();
    last_ = std::chrono::steady_clock::now();
  }
  std::mutex mutex_;
  std::condition_variable wake_;
  std::map<std::byte*, std::size_t> regions_;
  bool stop_ = false;
  std::size_t after_trim_ = 0;  // resident pages after the last trim
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
  std::thread thread_;
};

ResidentSetTrimmer& trimmer() {
  static ResidentSetTrimmer t;
  return t;
}

int open_scratch_file(const std::string& dir) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd >= 0) return fd;
  std::string name = dir + "/gcpipe-scratch-XXXXXX";  // a file system without O_TMPFILE
  fd = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd >= 0) ::unlink(name.c_str());
  return fd;
}

void warn_once_in_memory(const std::string& dir, int error) {
  static std::once_flag once;
  std::call_once(once, [&] {
    std::fprintf(stderr,
                 "gcpipe: warning: cannot make scratch files in %s (%s): long series are kept in memory, which "
                 "then grows with the program. Set GCPIPE_SCRATCH_DIR to a writable directory on disk.\n",
                 dir.c_str(), std::strerror(error));
  });
}

[[noreturn]] void no_room(std::size_t bytes, const std::string& dir, int error) {
  throw std::runtime_error("no room for " + std::to_string((bytes + (1 << 20) - 1) >> 20) + " MB of scratch series in " +
                           dir + " (" + std::strerror(error) +
                           "): free disk space or set GCPIPE_SCRATCH_DIR to a directory with room");
}

}  // namespace

void trim_scratch_if_grown() { trimmer().trim_if_grown(); }

std::string scratch_directory() {
  const char* dir = std::getenv("GCPIPE_SCRATCH_DIR");
  return dir && *dir ? dir : "/var/tmp";
}

void ScratchBytes::grow(std::size_t bytes) {
  if (bytes <= capacity_) return;
  bytes = whole_pages(bytes);
  if (fd_ < 0 && bytes >= kSpillBytes) move_to_file(bytes);
  if (bytes <= capacity_) return;  // moved to a file of that size
  if (fd_ < 0) return map_anonymous(bytes);
  // Disk for the new bytes now: a page written through the mapping where the disk is full would
  // kill the process with SIGBUS instead of saying so.
  if (const int e = ::posix_fallocate(fd_, static_cast<off_t>(capacity_), static_cast<off_t>(bytes - capacity_)); e != 0)
    no_room(bytes - capacity_, scratch_directory(), e);
  trimmer().remove(data_);
  void* p = ::mremap(data_, capacity_, bytes, MREMAP_MAYMOVE);
  if (p == MAP_FAILED) {
    trimmer().add(data_, capacity_);
    throw std::bad_alloc();
  }
  data_ = static_cast<std::byte*>(p);
  capacity_ = bytes;
  trimmer().add(data_, capacity_);
}

void ScratchBytes::reserve_address(std::size_t bytes) {
  release();
  bytes = whole_pages(std::max<std::size_t>(bytes, 1));
  const std::string dir = scratch_directory();
  const int fd = open_scratch_file(dir);
  if (fd < 0) {
    warn_once_in_memory(dir, errno);
    void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    data_ = static_cast<std::byte*>(p);
    capacity_ = backed_ = bytes;
    return;
  }
  void* p = MAP_FAILED;
  if (::ftruncate(fd, static_cast<off_t>(bytes)) == 0)  // sparse: no disk until back()
    p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) {
    ::close(fd);
    throw std::bad_alloc();
  }
  data_ = static_cast<std::byte*>(p);
  capacity_ = bytes;
  fd_ = fd;
  backed_ = 0;
  trimmer().add(data_, capacity_);
}

void ScratchBytes::back(std::size_t bytes) {
  if (bytes <= backed_) return;
  // In steps of kSpillBytes: a posix_fallocate call per value would cost more than the value.
  const std::size_t to = std::min(capacity_, (bytes + kSpillBytes - 1) / kSpillBytes * kSpillBytes);
  if (const int e = ::posix_fallocate(fd_, static_cast<off_t>(backed_), static_cast<off_t>(to - backed_)); e != 0)
    no_room(to - backed_, scratch_directory(), e);
  backed_ = to;
}

void ScratchBytes::map_anonymous(std::size_t bytes) {
  void* p = data_ ? ::mremap(data_, capacity_, bytes, MREMAP_MAYMOVE)
                  : ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  data_ = static_cast<std::byte*>(p);
  capacity_ = bytes;
}

void ScratchBytes::move_to_file(std::size_t bytes) {
  const std::string dir = scratch_directory();
  const int fd = open_scratch_file(dir);
  if (fd < 0) return warn_once_in_memory(dir, errno);
  if (const int e = ::posix_fallocate(fd, 0, static_cast<off_t>(bytes)); e != 0) {
    ::close(fd);
    no_room(bytes, dir, e);
  }
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) {
    ::close(fd);
    throw std::bad_alloc();
  }
  if (data_) {
    std::memcpy(p, data_, capacity_);
    ::munmap(data_, capacity_);
  }
  data_ = static_cast<std::byte*>(p);
  capacity_ = bytes;
  fd_ = fd;
  trimmer().add(data_, capacity_);
}

void ScratchBytes::shrink(std::size_t bytes) {
  bytes = whole_pages(std::max<std::size_t>(bytes, 1));
  if (!data_ || bytes >= capacity_) return;
  if (fd_ >= 0) trimmer().remove(data_);
  void* p = ::mremap(data_, capacity_, bytes, 0);  // shrinking in place never moves
  if (p != MAP_FAILED) {
    // The file's tail is disk only; if it cannot be cut, it goes with the file at release().
    if (fd_ >= 0 && ::ftruncate(fd_, static_cast<off_t>(bytes)) != 0) errno = 0;
    capacity_ = bytes;
  }
  if (fd_ >= 0) trimmer().add(data_, capacity_);
}

void ScratchBytes::discard_before(std::size_t bytes) {
  const std::size_t end = std::min(bytes / page_size() * page_size(), capacity_);
  if (end == 0) return;
  // A file's pages are freed on disk too (a hole reads as zeros, as a dropped anonymous page does).
  if (fd_ >= 0) ::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, 0, static_cast<off_t>(end));
  ::madvise(data_, end, MADV_DONTNEED);
}

void ScratchBytes::release() {
  if (!data_) return;
  if (fd_ >= 0) trimmer().remove(data_);
  ::munmap(data_, capacity_);
  if (fd_ >= 0) ::close(fd_);
  data_ = nullptr;
  capacity_ = backed_ = 0;
  fd_ = -1;
}

}  // namespace gcpipe
