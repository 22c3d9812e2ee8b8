// Internal to store/: the schema as a list of migrations. Version N is reached by applying
// migrations 1..N in order; a model records every version it passed through.
#pragma once

#include <sqlite3.h>

namespace sightmap::store::internal {

// PRAGMA application_id of every sightmap model ("SMAP"), which tells our files from other
// applications' SQLite databases without guessing from table names.
constexpr int kApplicationId = 0x534d4150;

int LatestSchemaVersion();

// Applies migrations from_version+1 .. to_version. The caller holds the transaction, so an upgrade
// is all or nothing.
void ApplyMigrations(sqlite3* db, int from_version, int to_version);

}  // namespace sightmap::store::internal
