#pragma once
#include <cstddef>
#include <cstdint>

namespace lw::hal {

/// Page store on NOR flash reserved for the application's persistent state. Erased bytes read
/// 0xFF; programming can only clear bits. Blocking (erase: milliseconds); not ISR-safe. A power
/// loss during Erase or Program may leave the page partially erased or programmed.
class FlashPages {
 public:
  /// Bytes per page (the erase unit). Constant for the life of the object. Non-blocking.
  size_t PageSize() { return DoPageSize(); }
  /// Pages reserved for the application (indices 0..PageCount()-1). Non-blocking.
  size_t PageCount() { return DoPageCount(); }
  /// Sets every byte of `page` to 0xFF. Blocking (milliseconds). Returns false on a bad index or a
  /// controller error; after a failure the page content is undefined.
  bool Erase(size_t page) { return DoErase(page); }
  /// Clears bits: each byte at `offset + i` becomes `old & data[i]`. The range must lie inside the
  /// page (else false, nothing written). Blocking; the port handles its program granularity
  /// (padding with 0xFF). Returns false on a controller error.
  bool Program(size_t page, size_t offset, const uint8_t* data, size_t len) { return DoProgram(page, offset, data, len); }
  /// Copies `len` bytes at `offset` of `page` into `data`. Blocking (microseconds); false when
  /// the range is outside the page.
  bool Read(size_t page, size_t offset, uint8_t* data, size_t len) { return DoRead(page, offset, data, len); }

 protected:
  ~FlashPages() = default;

 private:
  virtual size_t DoPageSize() = 0;
  virtual size_t DoPageCount() = 0;
  virtual bool DoErase(size_t page) = 0;
  virtual bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) = 0;
  virtual bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) = 0;
};

}  // namespace lw::hal
