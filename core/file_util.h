// File helpers with the project's error contract: every failure names the file and the problem, and
// writes go to "<path>.tmp.<pid>" first and are renamed into place, so a crash or Ctrl-C never leaves
// a partial output under the final name.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace lfgi {

// Reads a whole file. Throws lfgi::Error("<path>: <reason>") if it cannot be opened or read.
std::vector<std::byte> readFileBytes(const std::filesystem::path& path);
// Reads exactly `length` bytes at `offset` (positioned reads; safe from several threads). Throws
// lfgi::Error("<path>: <reason>") when the file is shorter or cannot be read.
std::vector<std::byte> readFileRange(const std::filesystem::path& path, uint64_t offset, uint64_t length);

// Writes bytes atomically (temp file + rename). Creates missing parent directories.
void writeFileAtomic(const std::filesystem::path& path, std::span<const std::byte> bytes);
void writeFileAtomic(const std::filesystem::path& path, const std::string& text);

// Calls write(tmpPath) to produce the file under a temporary name, then renames it to path. If write
// throws, the temporary file is removed and the exception propagates. For libraries (OpenEXR, stb)
// that insist on writing to a path themselves.
void writeViaTempFile(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmpPath)>& write);

}  // namespace lfgi
