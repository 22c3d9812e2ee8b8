// One writer per model: `sightmap map` and `label` hold the model's writer lock while they have it
// open for writing, and a second writer is refused with who holds it, instead of failing later
// inside SQLite or the mapper. Readers (`info`, `locate`, `serve`) take no lock and work beside a
// writer (SQLite's WAL lets them).
//
// The lock is an flock(2) on a file beside the model (MODEL.lock), which also records the
// holder's pid and start time. The kernel releases it when the holder exits, however it exits,
// so a killed writer never leaves a model locked.
#pragma once

#include <string>

namespace sightmap::store {

class WriterLock {
 public:
  // Takes the lock of the model at `model_path`. Throws sightmap::Error "model M is in use by
  // sightmap pid N since T ..." when another open model holds it (in this process too), or when
  // the lock file cannot be created.
  explicit WriterLock(const std::string& model_path);
  ~WriterLock();
  WriterLock(WriterLock&& other) noexcept;
  WriterLock& operator=(WriterLock&& other) noexcept;
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;

  static std::string LockPath(const std::string& model_path) { return model_path + ".lock"; }

 private:
  int fd_ = -1;
};

}  // namespace sightmap::store
