#include "app/json_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <set>
#include <stdexcept>
#include <vector>

namespace hgd {

std::string jsonPointerStep(const std::string& key) {
  std::string out = "/";
  for (const char ch : key) {
    const auto c = static_cast<unsigned char>(ch);
    if (ch == '~') {
      out += "~0";
    } else if (ch == '/') {
      out += "~1";
    } else if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out;
}

std::string readJsonFile(const std::string& path, const char* kind, std::uintmax_t max_bytes,
                         JsonRaise raise) {
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  const std::string cannot_open = path + ": cannot open " + kind + " file: ";
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) raise(cannot_open + std::strerror(errno));
  std::unique_ptr<std::FILE, Closer> file(::fdopen(fd, "rb"));
  if (!file) {
    const int e = errno;
    ::close(fd);
    raise(cannot_open + std::strerror(e));
  }
  struct stat st {};
  if (::fstat(::fileno(file.get()), &st) != 0) raise(cannot_open + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) raise(cannot_open + std::strerror(EISDIR));
  if (!S_ISREG(st.st_mode)) raise(cannot_open + "not a regular file");
  if (st.st_size == 0) raise(path + ": empty file");
  const auto size = static_cast<std::uintmax_t>(st.st_size);
  if (size > max_bytes)
    raise(path + ": file too large for a " + kind + " (" + std::to_string(size) + " bytes)");
  std::string text(static_cast<std::size_t>(size), '\0');
  if (std::fread(text.data(), 1, text.size(), file.get()) != text.size())
    raise(path + ": cannot read " + kind +
          " file: " + (std::ferror(file.get()) ? std::strerror(errno) : "the file shrank while being read"));
  return text;
}

namespace {

/// Follows the parse to name the JSON pointer of a duplicated key.
class DuplicateKeyCheck {
 public:
  explicit DuplicateKeyCheck(const JsonReader* reader) : reader_(reader) {}

  bool operator()(int /*depth*/, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    switch (event) {
      case E::object_start: frames_.push_back({false, 0, {}, {}}); break;
      case E::array_start: frames_.push_back({true, 0, {}, {}}); break;
      case E::key: {
        Frame& f = frames_.back();
        f.key = parsed.get<std::string>();
        if (!f.keys.insert(f.key).second) reader_->fail(path(), "duplicate key");
        break;
      }
      case E::object_end:
      case E::array_end:
        frames_.pop_back();
        completed();
        break;
      case E::value: completed(); break;
    }
    return true;
  }

 private:
  struct Frame {
    bool array;
    std::size_t index;
    std::string key;
    std::set<std::string> keys;
  };
  void completed() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
  }
  std::string path() const {
    std::string p;
    for (const Frame& f : frames_) p += f.array ? "/" + std::to_string(f.index) : jsonPointerStep(f.key);
    return p;
  }
  const JsonReader* reader_;
  std::vector<Frame> frames_;
};

}  // namespace

nlohmann::json JsonReader::parse(const std::string& text) const {
  try {
    return json::parse(text, DuplicateKeyCheck(this));
  } catch (const json::exception& e) {
    // Syntax errors and numbers out of range (1e400). nlohmann's message includes the byte
    // position; keep it.
    raise_(name_ + ": invalid JSON: " + e.what());
  }
  throw std::logic_error("JsonRaise returned");
}

void JsonReader::fail(const std::string& path, const std::string& what) const {
  raise_(name_ + ": " + (path.empty() ? "/" : path) + ": " + what);
  throw std::logic_error("JsonRaise returned");
}

std::string JsonReader::list(std::initializer_list<const char*> keys) {
  std::string out;
  for (const char* k : keys) out += std::string(out.empty() ? "" : ", ") + k;
  return out;
}

void JsonReader::onlyKeys(const json& j, const std::string& path,
                          std::initializer_list<const char*> keys) const {
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = false;
    for (const char* k : keys) known = known || it.key() == k;
    if (!known) fail(path + jsonPointerStep(it.key()), "unknown key (expected one of: " + list(keys) + ")");
  }
}

const nlohmann::json& JsonReader::object(const json& j, const std::string& path) const {
  if (!j.is_object()) fail(path, "must be an object");
  return j;
}

const nlohmann::json& JsonReader::objectWith(const json& j, const std::string& path,
                                             std::initializer_list<const char*> keys) const {
  onlyKeys(object(j, path), path, keys);
  return j;
}

const nlohmann::json& JsonReader::member(const json& j, const std::string& path, const char* key) const {
  const auto it = j.find(key);
  if (it == j.end()) fail(path + jsonPointerStep(key), "is required");
  return *it;
}

double JsonReader::number(const json& j, const std::string& path) const {
  if (!j.is_number()) fail(path, "must be a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) fail(path, "must be a finite number");
  return v;
}

}  // namespace hgd
