#include "store/writer_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <string>

#include "core/check.h"

namespace sightmap::store {
namespace {

std::string ReadHolder(int fd) {
  char text[128] = {};
  const ssize_t n = pread(fd, text, sizeof(text) - 1, 0);
  std::string holder(text, n > 0 ? static_cast<size_t>(n) : 0);
  while (!holder.empty() && (holder.back() == '\n' || holder.back() == '\0')) holder.pop_back();
  return holder.empty() ? "another sightmap" : holder;
}

std::string Now() {
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  localtime_r(&now, &local);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S", &local);
  return text;
}

}  // namespace

WriterLock::WriterLock(const std::string& model_path) {
  const std::string path = LockPath(model_path);
  fd_ = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    SIGHTMAP_THROW(Error, "cannot create the model's lock file " << path << ": "
                                                                 << std::strerror(errno)
                                                                 << "; make its folder writable");
  }
  if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    const std::string holder = error == EWOULDBLOCK ? ReadHolder(fd_) : std::string();
    close(fd_);
    fd_ = -1;
    if (error == EWOULDBLOCK) {
      SIGHTMAP_THROW(Error, "model " << model_path << " is in use by " << holder
                                     << ": wait until it finishes, or stop it");
    }
    SIGHTMAP_THROW(Error, "cannot lock " << path << ": " << std::strerror(error));
  }
  const std::string holder = "sightmap pid " + std::to_string(getpid()) + " since " + Now() + "\n";
  if (ftruncate(fd_, 0) == 0) {
    [[maybe_unused]] const ssize_t written = pwrite(fd_, holder.data(), holder.size(), 0);
  }
}

WriterLock::~WriterLock() {
  if (fd_ >= 0) close(fd_);  // releases the flock
}

WriterLock::WriterLock(WriterLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }

WriterLock& WriterLock::operator=(WriterLock&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) close(fd_);
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

}  // namespace sightmap::store
