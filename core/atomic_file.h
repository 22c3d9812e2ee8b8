// Files written whole or not at all, and durable once written: the bytes go to a temporary beside
// the target (PATH + suffix), which is flushed to the disk (fsync), renamed over the target, and
// the folder is flushed too so that the rename itself survives a power cut. A crash at any moment
// leaves the old file or the new one, never a torn one. Every file sightmap writes for people or
// other tools (images, PLY, trajectories, point lists) goes through here; the model has SQLite.
#pragma once

#include <fstream>
#include <string>
#include <string_view>

namespace sightmap {

class AtomicFile {
 public:
  // Creates PATH + temporary_suffix. Throws Error when it cannot (a missing or read-only folder).
  explicit AtomicFile(std::string path, std::string temporary_suffix = ".tmp");
  // Removes the temporary when Commit() was not reached: the target is left as it was.
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& out() { return out_; }
  const std::string& temporary_path() const { return temporary_; }

  // Flushes, fsyncs, renames over the target, fsyncs the folder. Throws Error naming the file and
  // why (a full disk); the temporary is removed then.
  void Commit();

 private:
  std::string path_;
  std::string temporary_;
  std::ofstream out_;
  bool committed_ = false;
};

// `bytes` to `path` through an AtomicFile.
void WriteFileAtomically(const std::string& path, std::string_view bytes);

// fsync of a written file, and of a folder after renames into it (several files made durable
// together, as a label export does). Throw Error when the system refuses.
void SyncFile(const std::string& path);
void SyncFolder(const std::string& folder);

}  // namespace sightmap
