#pragma once
/// Small RAII helpers over the SQLite C API shared by the gateway spool and the server store
/// (header-only: only targets that link SQLite include it). Errors throw `Error` (a
/// std::runtime_error type of the caller's) with "<what> <path>: <step>: <sqlite message>".
#include <sqlite3.h>

#include <cstring>

#include <cstdint>
#include <string>

namespace lw::core::sqlite {

/// An open database handle; closes on destruction.
template <class Error>
class Database {
 public:
  /// `what` names the file's role in messages ("spool", "database").
  Database(const std::string& path, const std::string& what, int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE)
      : path_(path), what_(what) {
    if (sqlite3_open_v2(path.c_str(), &db_, flags | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
      std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
      // SQLite's "unable to open database file" does not say why: the system's reason does
      // ("Read-only file system", "No such file or directory", "Permission denied").
      if (const int err = db_ ? sqlite3_system_errno(db_) : 0; err != 0) msg += std::string(" (") + std::strerror(err) + ")";
      sqlite3_close(db_);
      db_ = nullptr;
      throw Error(what_ + " " + path_ + ": cannot open: " + msg);
    }
    sqlite3_busy_timeout(db_, 5000);
  }
  ~Database() { sqlite3_close(db_); }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  sqlite3* get() const { return db_; }
  const std::string& path() const { return path_; }
  [[noreturn]] void Fail(const std::string& step) const {
    throw Error(what_ + " " + path_ + ": " + step + ": " + sqlite3_errmsg(db_));
  }
  void Exec(const char* sql) const {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string msg = err ? err : sqlite3_errmsg(db_);
      sqlite3_free(err);
      throw Error(what_ + " " + path_ + ": " + msg);
    }
  }

 private:
  sqlite3* db_ = nullptr;
  std::string path_;
  std::string what_;
};

/// A prepared statement; Reset() before reuse.
template <class Error>
class Statement {
 public:
  Statement(const Database<Error>& db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db.get(), sql, -1, &stmt_, nullptr) != SQLITE_OK) db_.Fail("prepare");
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Bind(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Statement& Bind(int i, int64_t v) {
    sqlite3_bind_int64(stmt_, i, v);
    return *this;
  }
  Statement& Bind(int i, int v) { return Bind(i, static_cast<int64_t>(v)); }
  Statement& Bind(int i, double v) {
    sqlite3_bind_double(stmt_, i, v);
    return *this;
  }
  /// Steps once: true when a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    db_.Fail("step");
  }
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  int64_t Int(int col) const { return sqlite3_column_int64(stmt_, col); }
  double Real(int col) const { return sqlite3_column_double(stmt_, col); }
  bool IsNull(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  std::string Text(int col) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    return p ? std::string(p, static_cast<size_t>(sqlite3_column_bytes(stmt_, col))) : std::string();
  }
  /// Rows changed by the last step of an INSERT/UPDATE/DELETE.
  int Changes() const { return sqlite3_changes(db_.get()); }

 private:
  const Database<Error>& db_;
  sqlite3_stmt* stmt_ = nullptr;
};

/// BEGIN IMMEDIATE; rolls back unless Commit() was called, so an exception mid-batch stores nothing.
template <class Error>
class Transaction {
 public:
  explicit Transaction(const Database<Error>& db) : db_(db) { db_.Exec("BEGIN IMMEDIATE"); }
  ~Transaction() {
    if (!done_) sqlite3_exec(db_.get(), "ROLLBACK", nullptr, nullptr, nullptr);
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void Commit() {
    db_.Exec("COMMIT");
    done_ = true;
  }

 private:
  const Database<Error>& db_;
  bool done_ = false;
};

}  // namespace lw::core::sqlite
