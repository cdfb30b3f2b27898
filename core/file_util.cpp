#include "core/file_util.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "core/error.h"

namespace lfgi {

std::vector<std::byte> readFileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) fail("{}: cannot open for reading ({})", path.string(), std::strerror(errno));
  // An ifstream opens a directory and reports a size of 2^63 - 1 (bad_alloc below), so name it instead.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail("{}: is a directory, not a file", path.string());
  const std::streamoff size = in.tellg();
  if (size < 0) fail("{}: cannot determine file size", path.string());
  std::vector<std::byte> bytes(static_cast<std::size_t>(size));
  in.seekg(0);
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size))
    fail("{}: read failed after {} of {} bytes", path.string(), in.gcount(), size);
  return bytes;
}

std::vector<std::byte> readFileRange(const std::filesystem::path& path, uint64_t offset, uint64_t length) {
  std::vector<std::byte> out(static_cast<size_t>(length));
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail("{}: cannot open for reading ({})", path.string(), std::strerror(errno));
  size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::pread(fd, out.data() + done, out.size() - done, off_t(offset + done));
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      fail("{}: cannot read {} bytes at offset {} ({})", path.string(), length, offset,
           n == 0 ? "the file ends first" : std::strerror(err));
    }
    done += size_t(n);
  }
  ::close(fd);
  return out;
}

void writeViaTempFile(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path&)>& write) {
  if (path.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(path.parent_path(), ec);
    if (ec) fail("{}: cannot create directory ({})", path.parent_path().string(), ec.message());
  }
  std::filesystem::path tmp = path;
  tmp += ".tmp." + std::to_string(::getpid());
  try {
    write(tmp);
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    fail("{}: cannot move finished file into place ({})", path.string(), ec.message());
  }
}

void writeFileAtomic(const std::filesystem::path& path, std::span<const std::byte> bytes) {
  writeViaTempFile(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) fail("{}: cannot open for writing ({})", tmp.string(), std::strerror(errno));
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) fail("{}: write failed ({})", tmp.string(), std::strerror(errno));
  });
}

void writeFileAtomic(const std::filesystem::path& path, const std::string& text) {
  writeFileAtomic(path, std::as_bytes(std::span(text.data(), text.size())));
}

}  // namespace lfgi
