#include "cpvs/net/chunked_stream.h"


namespace cpvs::net {

ChunkSource ChunkSource::ofBytes(const void* data, uint64_t size) {
  ChunkSource s;
  s.data_ = static_cast<const char*>(data);
  s.size_ = size;
  return s;
}

ChunkSource ChunkSource::ofFile(const std::string& path) {
  auto in = std::make_shared<std::ifstream>(path, std::ios::binary | std::ios::ate);
  if (!*in) throw FarmError(ErrorKind::Internal, "cannot read " + path);
  ChunkSource s;
  s.path_ = path;
  s.size_ = uint64_t(in->tellg());
  s.file_ = std::move(in);
  return s;
}

void ChunkSource::read(uint64_t offset, size_t n, std::string& out) const {
  if (data_ || n == 0) {
    out.assign(data_ ? data_ + offset : "", n);
    return;
  }
  file_->seekg(std::streamoff(offset));
  out.resize(n);
  if (!file_->read(out.data(), std::streamsize(n))) throw FarmError(ErrorKind::Internal, "cannot read " + path_);
}

void ChunkReceiver::fail(const std::string& why) const { throw FarmError(blame_, what_ + ": " + why); }

uint64_t ChunkReceiver::accept(std::optional<uint64_t> total, std::optional<uint64_t> offset, size_t size) {
  if (total) {
    if (!total_) {
      if (*total > maxTotal_)
        fail("size " + std::to_string(*total) + " is over the limit of " + std::to_string(maxTotal_) + " bytes");
      if (*total < offset_) fail("size " + std::to_string(*total) + " is less than the " + std::to_string(offset_) +
                                 " bytes already held");
      total_ = total;
    } else if (*total != *total_) {
      fail("the size changed from " + std::to_string(*total_) + " to " + std::to_string(*total) + " midway");
    }
  }
  if (!total_) fail("the first chunk announces no size");
  if (offset && *offset != offset_)
    fail("a chunk at byte " + std::to_string(*offset) + " where byte " + std::to_string(offset_) + " was expected");
  if (size > kChunkBytes)
    fail("a chunk of " + std::to_string(size) + " bytes; the limit is " + std::to_string(kChunkBytes));
  if (size > *total_ - offset_) fail("the data runs past its announced size of " + std::to_string(*total_) + " bytes");
  const uint64_t at = offset_;
  offset_ += size;
  return at;
}

void ChunkReceiver::finish() const {
  if (!total_) fail("no data");
  if (offset_ != *total_)
    fail("truncated: " + std::to_string(offset_) + " of " + std::to_string(*total_) + " bytes arrived");
}

}  // namespace cpvs::net
