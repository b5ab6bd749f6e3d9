// The one sender and the one receiver of every chunked transfer: scenes up (client) and
// down (worker), tile results (worker), artifacts (client). Every receiver applies the
// same rules to what it is sent, whichever side it is on.
#pragma once

#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "cpvs/net/channel.h"
#include "cpvs/net/status.h"

namespace cpvs::net {

/// Bytes to send: a buffer in memory (not copied: it must outlive the source) or a file.
class ChunkSource {
 public:
  static ChunkSource ofBytes(const void* data, uint64_t size);
  /// FarmError(Internal) when the file can't be read: the sender's own failure.
  static ChunkSource ofFile(const std::string& path);

  uint64_t size() const { return size_; }
  /// The bytes [offset, offset + n) into `out` (replacing its content).
  void read(uint64_t offset, size_t n, std::string& out) const;

 private:
  const char* data_ = nullptr;
  std::string path_;
  std::shared_ptr<std::ifstream> file_;  // opened once, read chunk by chunk
  uint64_t size_ = 0;
};

/// Sends the source's bytes from `offset` through `writer.Write(msg)` as consecutive
/// chunks of at most kChunkBytes. `fill(msg, chunkOffset, first)` sets each message's
/// other fields; the data is set here. At least one message goes out, even when there is
/// nothing left to send: the end of the stream is what the other side acts on. Returns
/// false when the other side ended the call (its status tells why). FarmError(OutOfRange)
/// when `offset` is past the end.
template <class Msg, class Writer, class Fill>
bool sendChunks(const ChunkSource& src, uint64_t offset, Writer& writer, Fill&& fill) {
  if (offset > src.size())
    throw FarmError(ErrorKind::OutOfRange, "offset " + std::to_string(offset) + " is past the end (" +
                                               std::to_string(src.size()) + " bytes)");
  std::string buffer;
  bool first = true;
  do {
    const uint64_t n = std::min<uint64_t>(kChunkBytes, src.size() - offset);
    Msg msg;
    fill(msg, offset, first);
    src.read(offset, size_t(n), buffer);
    msg.set_data(std::move(buffer));
    buffer = std::string();
    if (!writer.Write(msg)) return false;
    offset += n;
    first = false;
  } while (offset < src.size());
  return true;
}

/// The rules every receiver of a chunked stream applies: the first chunk that announces
/// a total fixes it (at most `maxTotal`), later announcements must repeat it; a chunk that
/// carries an offset must start where the data so far ends; no chunk holds more than
/// kChunkBytes or runs past the total; at the end every byte has arrived. A stream that
/// breaks a rule is the sender's fault: FarmError of kind `blame` (InvalidArgument when a
/// client or worker sent it, DataLoss when the coordinator did), naming `what`.
class ChunkReceiver {
 public:
  ChunkReceiver(uint64_t offset, uint64_t maxTotal, ErrorKind blame, std::string what)
      : offset_(offset), maxTotal_(maxTotal), blame_(blame), what_(std::move(what)) {}

  /// Checks one chunk of `size` bytes; returns the offset its data goes to.
  uint64_t accept(std::optional<uint64_t> total, std::optional<uint64_t> offset, size_t size);
  /// Throws unless a total was announced and every byte of it arrived.
  void finish() const;

  uint64_t received() const { return offset_; }
  uint64_t total() const { return total_.value_or(0); }

 private:
  [[noreturn]] void fail(const std::string& why) const;

  uint64_t offset_, maxTotal_;
  ErrorKind blame_;
  std::string what_;
  std::optional<uint64_t> total_;
};

}  // namespace cpvs::net
