"""xz's ARM64 branch filter (BCJ), over a whole archive: Python's lzma module offers x86's but not this one.

ARM64 instructions are 4-byte little-endian words at multiples of 4 (in a tar archive too: its files start at
multiples of 512). The filter rewrites the immediates of two instructions, relative to the instruction's address
``pc`` (its offset in the data), as absolute values, so that calls of one function, and references to one page,
have the same bytes wherever they are (LZMA then finds more repeats):

- BL (``word >> 26 == 0b100101``): its 26-bit word offset becomes ``offset + pc / 4`` (modulo 2^26);
- ADRP (``word & 0x9F000000 == 0x90000000``): its 21-bit page offset (``immhi:immlo``), where it lies within
  +-2^17 pages, becomes ``pages + pc / 4096``, kept as 18 bits sign-extended to 21 (others are left as they are: an
  encoded value lies in the same range, so decoding finds exactly the words encoding changed).

Decoding subtracts instead. The loader's decoder is ``unfilter_arm64`` in ``loader/carried.c``; xz-utils 5.4 and
newer read the result (``xz --format=raw --arm64``).
"""

#: BL's opcode (the top 6 bits) and the mask of its 26-bit word offset
BL, BL_OFFSET = 0x25, 0x03FFFFFF
#: ADRP's opcode bits and their mask
ADRP, ADRP_MASK = 0x90000000, 0x9F000000


def arm64_branches(data, encode):
    """``data`` (bytes) with the BL and ADRP immediates made absolute (``encode``) or relative again (not ``encode``);
    a last partial word is kept as it is."""
    import numpy as np  # here: the command line's help imports the FMU build, and no numerical module

    n = len(data) // 4
    words = np.frombuffer(data, dtype="<u4", count=n).copy()
    pc = np.arange(0, 4 * n, 4, dtype=np.uint32)
    bl = (words >> 26) == BL
    moved = np.uint32(0x94000000) | (_moved(words, pc >> 2, encode) & np.uint32(BL_OFFSET))
    words[bl] = moved[bl]
    pages = ((words >> 29) & 3) | ((words >> 3) & np.uint32(0x001FFFFC))
    adrp = ((words & np.uint32(ADRP_MASK)) == ADRP) & (((pages + np.uint32(0x20000)) & np.uint32(0x1C0000)) == 0)
    pages = _moved(pages, pc >> 12, encode)
    moved = ((words & np.uint32(0x9000001F)) | ((pages & 3) << 29) | ((pages & np.uint32(0x3FFFC)) << 3)
             | ((np.uint32(0) - (pages & np.uint32(0x20000))) & np.uint32(0xE00000)))
    words[adrp] = moved[adrp]
    return words.astype("<u4").tobytes() + data[4 * n:]


def _moved(values, by, encode):
    """``values + by`` (``encode``) or ``values - by``, modulo 2^32 (numpy arrays of uint32)."""
    return values + by if encode else values - by
