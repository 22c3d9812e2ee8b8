// Internal to store/: thin RAII over the sqlite3 C API. Not a public header (it includes
// sqlite3.h); only store/*.cc include it.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <string>
#include <vector>

#include "core/check.h"

namespace sightmap::store::internal {

// Turns a failed sqlite3 return code into sightmap::Error with SQLite's own explanation, and a hint
// when the cause is one the user can fix (full disk, read-only file).
[[noreturn]] void ThrowSqliteError(sqlite3* db, int code, const char* call, const char* file,
                                   int line);

// SIGHTMAP_SQLITE3_CALL(db, sqlite3_exec(...)): every sqlite3 call goes through this (as COLMAP's
// SQLITE3_CALL), so no return code is silently dropped.
#define SIGHTMAP_SQLITE3_CALL(db, call)                                                       \
  do {                                                                                        \
    const int sightmap_sqlite_rc_ = (call);                                                   \
    if (sightmap_sqlite_rc_ != SQLITE_OK && sightmap_sqlite_rc_ != SQLITE_ROW &&              \
        sightmap_sqlite_rc_ != SQLITE_DONE) {                                                 \
      ::sightmap::store::internal::ThrowSqliteError(db, sightmap_sqlite_rc_, #call, __FILE__, \
                                                    __LINE__);                                \
    }                                                                                         \
  } while (false)

// Runs one or more statements without results.
void Exec(sqlite3* db, const std::string& sql);

// A prepared statement, finalized on destruction. Bind indices are 1-based as in SQLite.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql);
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Bind(int index, int64_t value);
  Statement& Bind(int index, int value) { return Bind(index, static_cast<int64_t>(value)); }
  Statement& Bind(int index, double value);
  Statement& Bind(int index, const std::string& text);
  Statement& BindBlob(int index, const void* data, size_t size);
  Statement& BindNull(int index);

  // Advances; true while a row is available. Throws on any error.
  bool Step();
  // Steps a statement that returns no rows, then resets it for reuse.
  void Run();
  void Reset();

  int64_t Int(int column) const;
  double Double(int column) const;
  std::string Text(int column) const;
  std::vector<uint8_t> Blob(int column) const;
  bool IsNull(int column) const;

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

// BEGIN IMMEDIATE ... COMMIT; rolls back unless Commit() was called (an exception unwinding through
// it leaves the database as before the transaction). IMMEDIATE takes the write lock up front, so a
// concurrent writer fails at BEGIN instead of half-way through.
class Transaction {
 public:
  explicit Transaction(sqlite3* db);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void Commit();

 private:
  sqlite3* db_;
  bool done_ = false;
};

}  // namespace sightmap::store::internal
