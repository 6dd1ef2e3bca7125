#pragma once
/// Writing a file so that a reader (or a crash) sees either the old content or the new, never a
/// part: write a temporary beside it, flush (and, when durable, fsync), then rename over the target.
/// The one helper every host program uses for its output files.
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>

namespace lw::core {

enum class Durability {
  kSynced,  ///< fsync the temporary before the rename and the folder after: survives a power cut
  kAtomic,  ///< rename only: readers never see a part (for files rewritten many times a second)
};

/// Writes `text` to `path` atomically. Throws std::runtime_error naming the path and the reason
/// (the temporary is removed; the old file, if any, is untouched).
void WriteFileAtomically(const std::filesystem::path& path, std::string_view text, Durability durability = Durability::kSynced);

/// The same, with the content streamed by `write` (for large files); an exception thrown by `write`
/// removes the temporary and propagates.
void WriteFileAtomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                         Durability durability = Durability::kSynced);

/// Copies `from` over `to` atomically (the same guarantees).
void CopyFileAtomically(const std::filesystem::path& from, const std::filesystem::path& to,
                        Durability durability = Durability::kSynced);

/// Makes file `path` whole or not at all when something else writes it (SQLite's backup API, a
/// library given a file name): `fill` creates and finishes the temporary whose path it is given,
/// which is then renamed over `path` (the same guarantees). An exception from `fill` removes the
/// temporary and propagates.
void MakeFileAtomically(const std::filesystem::path& path, const std::function<void(const std::filesystem::path& tmp)>& fill,
                        Durability durability = Durability::kSynced);

/// Makes folder `dir` whole or not at all: `fill` writes into a temporary sibling folder, which is
/// renamed to `dir` when it returns. `dir` must not exist or be an empty folder (std::runtime_error
/// naming it, with `what` as the prefix); an exception from `fill` removes the temporary and propagates.
void WriteFolderAtomically(const std::filesystem::path& dir, const std::function<void(const std::filesystem::path& tmp)>& fill,
                           const std::string& what = "output");

}  // namespace lw::core
