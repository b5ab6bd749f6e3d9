// Little-endian byte writing and bounds-checked reading: what every reader and writer of
// io builds on. Every read names what it reads, so a short input reports where it ended.
// Private to io.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/vec3.h"

namespace cpvs {

// The formats are little-endian and written with raw copies.
static_assert(std::endian::native == std::endian::little, "the artifact formats are little-endian");

class ByteWriter {
 public:
  std::vector<uint8_t> bytes;
  template <class T>
  void put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    size_t at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &v, sizeof(T));
  }
  void putVec(const Vec3& v) {
    put(v.x);
    put(v.y);
    put(v.z);
  }
  void raw(const void* p, size_t n) {
    size_t at = bytes.size();
    bytes.resize(at + n);
    if (n) std::memcpy(bytes.data() + at, p, n);
  }
};

class ByteReader {
 public:
  ByteReader(const uint8_t* d, size_t n, const std::string& src) : data_(d), size_(n), source_(src) {}
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  Vec3 getVec(const char* what) {
    Vec3 v;
    v.x = get<double>(what);
    v.y = get<double>(what);
    v.z = get<double>(what);
    return v;
  }
  const uint8_t* take(size_t n, const char* what) {
    need(n, what);
    const uint8_t* p = data_ + pos_;
    pos_ += n;
    return p;
  }
  /// Copies n bytes into `out` (which may be null when n is 0).
  void copy(void* out, size_t n, const char* what) {
    const uint8_t* src = take(n, what);
    if (n) std::memcpy(out, src, n);
  }
  size_t pos() const { return pos_; }
  const std::string& source() const { return source_; }
  size_t remaining() const { return size_ - pos_; }
  [[noreturn]] void fail(const std::string& msg) const { throw FormatError(source_ + ": " + msg); }

 private:
  void need(size_t n, const char* what) const {
    if (n > size_ - pos_)
      fail(std::string("truncated: the file ends inside the ") + what + " (at byte " +
           std::to_string(pos_) + " of " + std::to_string(size_) + ")");
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string source_;
};



}  // namespace cpvs
