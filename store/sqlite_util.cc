#include "store/sqlite_util.h"

#include <cstring>

namespace sightmap::store::internal {

void ThrowSqliteError(sqlite3* db, int code, const char* call, const char* file, int line) {
  const char* path = db ? sqlite3_db_filename(db, "main") : nullptr;
  const std::string where = (path && *path) ? std::string(path) : std::string("the model");
  std::string detail = sqlite3_errstr(code);
  if (db && sqlite3_errcode(db) == code) {
    const char* message = sqlite3_errmsg(db);
    if (message && detail != message) detail += std::string(" (") + message + ")";
  }
  const int primary = code & 0xff;
  if (primary == SQLITE_FULL || code == SQLITE_IOERR_WRITE || code == SQLITE_IOERR_FSYNC ||
      code == SQLITE_IOERR_TRUNCATE) {
    throw Error("cannot write model " + where + " (" + detail +
                    "): free disk space (or raise the file-size limit) and run again; the model "
                    "keeps everything written before this",
                (std::string(file) + " [" + call + "]").c_str(), line);
  }
  std::string hint;
  if (primary == SQLITE_READONLY) {
    hint =
        ": make the file and its folder writable (chmod u+w) or copy the model somewhere "
        "writable";
  } else if (primary == SQLITE_BUSY || primary == SQLITE_LOCKED) {
    hint = ": another sightmap process is writing this model; wait for it or close it";
  } else if (primary == SQLITE_CORRUPT || primary == SQLITE_NOTADB) {
    hint = ": the file is damaged or not a sightmap model; restore it from a backup";
  }
  // The failing call goes to the location (for logs), not into the user's sentence.
  const std::string location = std::string(file) + " [" + call + "]";
  throw Error("SQLite error on model " + where + ": " + detail + hint, location.c_str(), line);
}

void Exec(sqlite3* db, const std::string& sql) {
  char* message = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message);
  sqlite3_free(message);  // errmsg on the connection carries the same text
  SIGHTMAP_SQLITE3_CALL(db, rc);
}

Statement::Statement(sqlite3* db, const std::string& sql) : db_(db) {
  SIGHTMAP_SQLITE3_CALL(db_, sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt_, nullptr));
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement& Statement::Bind(int index, int64_t value) {
  SIGHTMAP_SQLITE3_CALL(db_, sqlite3_bind_int64(stmt_, index, value));
  return *this;
}

Statement& Statement::Bind(int index, double value) {
  SIGHTMAP_SQLITE3_CALL(db_, sqlite3_bind_double(stmt_, index, value));
  return *this;
}

Statement& Statement::Bind(int index, const std::string& text) {
  SIGHTMAP_SQLITE3_CALL(db_, sqlite3_bind_text(stmt_, index, text.data(),
                                               static_cast<int>(text.size()), SQLITE_TRANSIENT));
  return *this;
}

Statement& Statement::BindBlob(int index, const void* data, size_t size) {
  // A zero-length blob must not be bound as NULL: NOT NULL columns accept an empty blob.
  static const char kEmpty = 0;
  SIGHTMAP_SQLITE3_CALL(
      db_, sqlite3_bind_blob64(stmt_, index, size ? data : &kEmpty, size, SQLITE_STATIC));
  return *this;
}

Statement& Statement::BindNull(int index) {
  SIGHTMAP_SQLITE3_CALL(db_, sqlite3_bind_null(stmt_, index));
  return *this;
}

bool Statement::Step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  // sqlite3_step's own code can be generic; the connection holds the extended one.
  sqlite3_reset(stmt_);
  ThrowSqliteError(db_, sqlite3_extended_errcode(db_), "sqlite3_step", __FILE__, __LINE__);
}

void Statement::Run() {
  Step();
  Reset();
}

void Statement::Reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

int64_t Statement::Int(int column) const { return sqlite3_column_int64(stmt_, column); }

double Statement::Double(int column) const { return sqlite3_column_double(stmt_, column); }

std::string Statement::Text(int column) const {
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  return text ? std::string(reinterpret_cast<const char*>(text), static_cast<size_t>(size))
              : std::string();
}

std::vector<uint8_t> Statement::Blob(int column) const {
  const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(stmt_, column));
  const int size = sqlite3_column_bytes(stmt_, column);
  return data ? std::vector<uint8_t>(data, data + size) : std::vector<uint8_t>();
}

bool Statement::IsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

Transaction::Transaction(sqlite3* db) : db_(db) { Exec(db_, "BEGIN IMMEDIATE"); }

Transaction::~Transaction() {
  if (!done_) {
    // Never throws from a destructor; a failed rollback leaves SQLite to roll back on next open.
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
}

void Transaction::Commit() {
  Exec(db_, "COMMIT");
  done_ = true;
}

}  // namespace sightmap::store::internal
