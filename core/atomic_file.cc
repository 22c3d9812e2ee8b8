#include "core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

#include "core/check.h"

namespace sightmap {
namespace {

void Sync(const std::string& path, int flags, const char* what) {
  const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
  SIGHTMAP_CHECK(fd >= 0,
                 "cannot open " << what << " " << path << " to flush it: " << std::strerror(errno));
  const int synced = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  SIGHTMAP_CHECK(synced == 0, "cannot flush " << what << " " << path
                                              << " to the disk: " << std::strerror(error));
}

std::string FolderOf(const std::string& path) {
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  return folder.empty() ? "." : folder.string();
}

}  // namespace

void SyncFile(const std::string& path) { Sync(path, O_RDONLY, "file"); }

void SyncFolder(const std::string& folder) { Sync(folder, O_RDONLY | O_DIRECTORY, "folder"); }

AtomicFile::AtomicFile(std::string path, std::string temporary_suffix)
    : path_(std::move(path)), temporary_(path_ + temporary_suffix) {
  out_.open(temporary_, std::ios::binary | std::ios::trunc);
  SIGHTMAP_CHECK(out_.is_open(),
                 "cannot write " << path_ << ": check that its folder exists and is writable");
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  out_.close();
  std::remove(temporary_.c_str());
}

void AtomicFile::Commit() {
  SIGHTMAP_CHECK(!committed_, "AtomicFile::Commit twice for " << path_);
  out_.flush();
  const bool written = out_.good();
  out_.close();
  if (!written || out_.fail()) {
    std::remove(temporary_.c_str());
    SIGHTMAP_THROW(Error, "cannot write " << path_ << ": is the disk full?");
  }
  try {
    SyncFile(temporary_);
    std::error_code error;
    std::filesystem::rename(temporary_, path_, error);
    SIGHTMAP_CHECK(!error, "cannot write " << path_ << ": " << error.message());
    committed_ = true;
    SyncFolder(FolderOf(path_));
  } catch (const Error&) {
    if (!committed_) std::remove(temporary_.c_str());
    throw;
  }
}

void WriteFileAtomically(const std::string& path, std::string_view bytes) {
  AtomicFile file(path);
  file.out().write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  file.Commit();
}

}  // namespace sightmap
