// Items handed to a consumer on a second thread, in order: the producer (a simulation) makes the
// next items while the consumer (the contour evaluation, the trace writer) handles the earlier
// ones. Items go over in chunks through a short queue, so memory stays bounded (the producer waits
// when the consumer is `queued` chunks behind), and each chunk is handed back to be filled again
// (a fresh chunk per hand-over cost a page fault per 4 KiB on the VM measured, about 10 us each).
// An exception of the consumer stops it and is thrown again from the producer's next hand-over or
// from finish(), so a failing consumer can never leave the producer waiting.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace gcpipe {

template <class T>
class ChunkedWorker {
 public:
  using Consume = std::function<void(const std::vector<T>&)>;

  ChunkedWorker(std::size_t chunk, std::size_t queued, Consume consume)
      : chunk_size_(chunk), queued_(queued), consume_(std::move(consume)), worker_([this] { run(); }) {
    chunk_.reserve(chunk_size_);
  }
  /// Without finish(): what is still queued is dropped (the run was abandoned).
  ~ChunkedWorker() { stop(/*abandon=*/true); }
  ChunkedWorker(const ChunkedWorker&) = delete;
  ChunkedWorker& operator=(const ChunkedWorker&) = delete;

  void push(const T& item) {
    chunk_.push_back(item);
    if (chunk_.size() == chunk_size_) hand_over();
  }
  /// Waits until every item pushed has been consumed; rethrows the consumer's exception.
  void finish() {
    hand_over();
    stop(/*abandon=*/false);
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void hand_over() {
    std::unique_lock lock(mutex_);
    room_.wait(lock, [&] { return queue_.size() < queued_ || failed_; });
    if (failed_) std::rethrow_exception(error_);
    queue_.push_back(std::move(chunk_));
    chunk_.clear();
    if (!spare_.empty()) {
      chunk_ = std::move(spare_.back());
      spare_.pop_back();
    }
    chunk_.reserve(chunk_size_);
    ready_.notify_one();
  }
  void stop(bool abandon) {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
      abandon_ = abandon;
    }
    ready_.notify_one();
    if (worker_.joinable()) worker_.join();
  }
  void run() {
    std::vector<T> items;
    while (true) {
      {
        std::unique_lock lock(mutex_);
        if (items.capacity() != 0) spare_.push_back(std::move(items)), items = {};
        ready_.wait(lock, [&] { return !queue_.empty() || done_; });
        if (queue_.empty() || abandon_) return;
        items = std::move(queue_.front());
        queue_.pop_front();
      }
      room_.notify_one();
      try {
        consume_(items);
      } catch (...) {
        std::lock_guard lock(mutex_);
        error_ = std::current_exception();
        failed_ = true;
        room_.notify_one();
        return;
      }
      items.clear();
    }
  }

  const std::size_t chunk_size_, queued_;
  Consume consume_;
  std::vector<T> chunk_;
  std::deque<std::vector<T>> queue_;
  std::vector<std::vector<T>> spare_;  //!< consumed chunks, to be filled again
  std::mutex mutex_;
  std::condition_variable ready_, room_;
  bool done_ = false, abandon_ = false, failed_ = false;
  std::exception_ptr error_;
  std::thread worker_;  // last: it starts once everything above exists
};

}  // namespace gcpipe
