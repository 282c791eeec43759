/* The CPython the FMU carries (carried.h), unpacked where it is started.
 *
 * The build packs each platform's CPython into one file of the FMU, SBF_CARRIED_PACK (relative to the FMU's root,
 * two folders above this library): a POSIX tar archive run through the branch filter of the platform's machine code
 * (SBF_CARRIED_FILTER) and compressed with LZMA (the ".lzma" format of xz-utils), outside binaries/ and resources/,
 * so that a host extracting only those (FMPy) writes none of it. A Linux platform's standard-library zip lies in
 * another such archive, SBF_CARRIED_SHARED_PACK, below SBF_CARRIED_SHARED_PREFIX, with the other Linux platforms'
 * (byte code of the same modules: together they compress to little more than one).
 * The first time this loader needs a file of that CPython, it unpacks the archives into a folder of the user's cache
 * named after their content (SBF_CARRIED_KEY), and every later process finds it there:
 *   - the folder is SBF_CARRIED_KEY in $SBF_PYTHON_CACHE, else in the user's cache (sbf_cache_root:
 *     $XDG_CACHE_HOME/stickslip/python or ~/.cache/stickslip/python; %LOCALAPPDATA%\stickslip\python), else, where
 *     none of these variables is set, "python" in the FMU's binaries folder (beside this library);
 *   - a folder is used only if it holds every file of SBF_CARRIED_FILES with its size; the archives are unpacked into a
 *     folder of a name of this process and thread's own, which is then renamed to the key (atomic): two processes or
 *     threads unpacking at once each write their own, the first rename wins and the others use it; a folder that
 *     lost files (deleted while a host ran) is moved aside, removed and unpacked again;
 *   - a failure (the archive missing because the host did not extract it, a folder that cannot be made or written,
 *     a full disk) is a message naming the folder, the system's reason and what to set.
 * The decoder is LZMA's reference algorithm (Igor Pavlov's public-domain LzmaSpec), for the whole archive in memory.
 */
#include "carried.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "platform.h"

#ifndef SBF_CARRIED_PACK
#define SBF_CARRIED_PACK ""
#endif
#ifndef SBF_CARRIED_KEY
#define SBF_CARRIED_KEY ""
#endif
/* the size of the tar archive the LZMA stream holds */
#ifndef SBF_CARRIED_TAR_SIZE
#define SBF_CARRIED_TAR_SIZE 0
#endif
/* the branch filter the build ran over the tar archive before compressing it (packing.py), undone after decoding:
 * 0 none, 1 x86 (x86_64 Linux and Windows), 2 ARM64 (aarch64 Linux) */
#ifndef SBF_CARRIED_FILTER
#define SBF_CARRIED_FILTER 0
#endif
/* the FMU's archive of what the Linux platforms' CPythons share (their standard-library zips, packing.py), and the
 * folder in it of this platform's files; "" if none */
#ifndef SBF_CARRIED_SHARED_PACK
#define SBF_CARRIED_SHARED_PACK ""
#endif
#ifndef SBF_CARRIED_SHARED_PREFIX
#define SBF_CARRIED_SHARED_PREFIX ""
#endif
/* {path in the archives, size in bytes}, ... of every file the CPython has (its own archive's and the shared one's) */
#ifndef SBF_CARRIED_FILES
#define SBF_CARRIED_FILES
#endif
#define CACHE_VARIABLE "SBF_PYTHON_CACHE"
#define LIBPYTHON_VARIABLE "SBF_LIBPYTHON"
/* the folder the build's paths of the carried CPython start with (SBF_BUNDLED_LIBPYTHON...) */
#define CARRIED_PREFIX "python"

static const struct { const char *name; long long size; } carried_files[] = {SBF_CARRIED_FILES {NULL, 0}};

/* ---- LZMA ---- */
typedef struct {
    const unsigned char *in, *end;
    uint32_t range, code;
    int corrupt;
} Range;

static unsigned next_byte(Range *rc)
{
    if (rc->in < rc->end) return *rc->in++;
    rc->corrupt = 1;
    return 0;
}

static void normalize(Range *rc)
{
    if (rc->range < (1u << 24)) {
        rc->range <<= 8;
        rc->code = (rc->code << 8) | next_byte(rc);
    }
}

static unsigned bit(Range *rc, uint16_t *prob)
{
    uint32_t bound = (rc->range >> 11) * *prob;
    unsigned symbol;
    if (rc->code < bound) {
        *prob += ((1u << 11) - *prob) >> 5;
        rc->range = bound;
        symbol = 0;
    } else {
        *prob -= *prob >> 5;
        rc->code -= bound;
        rc->range -= bound;
        symbol = 1;
    }
    normalize(rc);
    return symbol;
}

static uint32_t direct_bits(Range *rc, unsigned n)
{
    uint32_t result = 0;
    while (n--) {
        rc->range >>= 1;
        rc->code -= rc->range;
        uint32_t t = 0u - (rc->code >> 31);
        rc->code += rc->range & t;
        normalize(rc);
        result = (result << 1) + (t + 1);
    }
    return result;
}

static unsigned tree(Range *rc, uint16_t *probs, unsigned n)
{
    unsigned m = 1;
    for (unsigned i = 0; i < n; ++i) m = (m << 1) + bit(rc, &probs[m]);
    return m - (1u << n);
}

static unsigned reverse_tree(Range *rc, uint16_t *probs, unsigned n)
{
    unsigned m = 1, symbol = 0;
    for (unsigned i = 0; i < n; ++i) {
        unsigned b = bit(rc, &probs[m]);
        m = (m << 1) + b;
        symbol |= b << i;
    }
    return symbol;
}

typedef struct { uint16_t choice, choice2, low[16][8], mid[16][8], high[256]; } Lengths;

static unsigned length(Range *rc, Lengths *l, unsigned pos_state)
{
    if (!bit(rc, &l->choice)) return tree(rc, l->low[pos_state], 3);
    if (!bit(rc, &l->choice2)) return 8 + tree(rc, l->mid[pos_state], 3);
    return 16 + tree(rc, l->high, 8);
}

typedef struct {
    uint16_t is_match[12 << 4], is_rep[12], is_rep_g0[12], is_rep_g1[12], is_rep_g2[12], is_rep0_long[12 << 4];
    uint16_t slot[4][64], special[115], align[16];
    Lengths len, rep_len;
} Model;

static void init_probs(uint16_t *probs, size_t n)
{
    for (size_t i = 0; i < n; ++i) probs[i] = 1024;
}

static uint32_t distance(Range *rc, Model *m, unsigned len)
{
    unsigned slot = tree(rc, m->slot[len < 3 ? len : 3], 6);
    if (slot < 4) return slot;
    unsigned n = (slot >> 1) - 1;
    uint32_t dist = (2u | (slot & 1)) << n;
    if (slot < 14) return dist + reverse_tree(rc, m->special + dist - slot, n);
    return dist + (direct_bits(rc, n - 4) << 4) + reverse_tree(rc, m->align, 4);
}

/* Room for `more` bytes at `pos` in *out (`*capacity` bytes), which `grows` (doubling) or not; 0 if there is none */
static int room(unsigned char **out, size_t *capacity, size_t pos, size_t more, int grows)
{
    if (more <= *capacity - pos) return 1;
    size_t wanted = *capacity * 2 > pos + more ? *capacity * 2 : pos + more;
    unsigned char *bigger = grows ? realloc(*out, wanted) : NULL;
    if (!bigger) return 0;
    *out = bigger;
    *capacity = wanted;
    return 1;
}

/* The ".lzma" stream `in` (`n` bytes) decoded into *out_p (malloc'd), `*size_p` bytes: exactly what the stream
 * holds, or 0 where that is unknown (then *size_p is set to what it held); 0 with why not. */
static int lzma_decode(const unsigned char *in, size_t n, unsigned char **out_p, size_t *size_p, char *why,
                       size_t why_size)
{
    if (n < 13 || in[0] >= 9 * 5 * 5) return snprintf(why, why_size, "it is no LZMA stream"), 0;
    unsigned lc = in[0] % 9, lp = (in[0] / 9) % 5, pb = in[0] / 45;
    size_t size = *size_p, capacity = size ? size : 4 * n;
    int grows = size == 0;
    Model *m = malloc(sizeof *m);
    uint16_t *literals = malloc(sizeof(uint16_t) * (0x300u << (lc + lp)));
    unsigned char *out = malloc(capacity);
    if (!m || !literals || !out)
        return free(m), free(literals), free(out), snprintf(why, why_size, "out of memory"), 0;
    init_probs((uint16_t *)m, sizeof *m / sizeof(uint16_t));
    init_probs(literals, 0x300u << (lc + lp));
    Range rc = {in + 13, in + n, 0xFFFFFFFFu, 0, 0};
    if (next_byte(&rc) != 0) rc.corrupt = 1;
    for (int i = 0; i < 4; ++i) rc.code = (rc.code << 8) | next_byte(&rc);
    size_t pos = 0;
    uint32_t rep[4] = {0, 0, 0, 0};
    unsigned state = 0;
    int ok = 0;
    while (!rc.corrupt) {
        unsigned pos_state = pos & ((1u << pb) - 1);
        if (!bit(&rc, &m->is_match[(state << 4) + pos_state])) { /* a literal */
            if (!room(&out, &capacity, pos, 1, grows)) break;
            unsigned previous = pos ? out[pos - 1] : 0, symbol = 1;
            uint16_t *probs = literals + 0x300u * (((pos & ((1u << lp) - 1)) << lc) + (previous >> (8 - lc)));
            if (state >= 7) {
                unsigned match = out[pos - rep[0] - 1];
                do {
                    unsigned match_bit = (match >> 7) & 1;
                    match <<= 1;
                    unsigned b = bit(&rc, &probs[((1 + match_bit) << 8) + symbol]);
                    symbol = (symbol << 1) | b;
                    if (match_bit != b) break;
                } while (symbol < 0x100);
            }
            while (symbol < 0x100) symbol = (symbol << 1) | bit(&rc, &probs[symbol]);
            out[pos++] = (unsigned char)(symbol - 0x100);
            state = state < 4 ? 0 : state < 10 ? state - 3 : state - 6;
            continue;
        }
        unsigned len;
        if (bit(&rc, &m->is_rep[state])) {
            if (pos == 0) break;
            if (!bit(&rc, &m->is_rep_g0[state])) {
                if (!bit(&rc, &m->is_rep0_long[(state << 4) + pos_state])) { /* one byte at rep0 */
                    if (!room(&out, &capacity, pos, 1, grows)) break;
                    state = state < 7 ? 9 : 11;
                    out[pos] = out[pos - rep[0] - 1];
                    ++pos;
                    continue;
                }
            } else {
                uint32_t dist;
                if (!bit(&rc, &m->is_rep_g1[state]))
                    dist = rep[1];
                else {
                    if (!bit(&rc, &m->is_rep_g2[state]))
                        dist = rep[2];
                    else
                        dist = rep[3], rep[3] = rep[2];
                    rep[2] = rep[1];
                }
                rep[1] = rep[0];
                rep[0] = dist;
            }
            len = length(&rc, &m->rep_len, pos_state);
            state = state < 7 ? 8 : 11;
        } else {
            rep[3] = rep[2], rep[2] = rep[1], rep[1] = rep[0];
            len = length(&rc, &m->len, pos_state);
            state = state < 7 ? 7 : 10;
            rep[0] = distance(&rc, m, len);
            if (rep[0] == 0xFFFFFFFFu) { /* the end marker */
                ok = (grows || pos == size) && rc.code == 0;
                break;
            }
        }
        len += 2;
        if (rep[0] >= pos || !room(&out, &capacity, pos, len, grows)) break;
        for (; len; --len, ++pos) out[pos] = out[pos - rep[0] - 1];
    }
    free(m);
    free(literals);
    if (!ok) {
        free(out);
        return snprintf(why, why_size, "it is damaged (decoding stopped at byte %zu of %zu)", pos, size), 0;
    }
    *out_p = out;
    *size_p = pos;
    return 1;
}

/* ---- the branch filters (xz's x86 and ARM64 BCJ filters, decoding) ----
 * Machine code's calls and jumps hold addresses relative to the instruction, which the build's filter made absolute
 * (the same callee then has the same bytes everywhere, which LZMA compresses better); these make them relative
 * again, in place, counting positions from the start of the tar archive. */

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_le32(unsigned char *p, uint32_t value)
{
    for (int i = 0; i < 4; ++i) p[i] = (unsigned char)(value >> (8 * i));
}

/* x86: the 32-bit operand of a call (E8) or jump (E9) whose top byte is 00 or FF (a displacement within 16 MB),
 * then skipped. An E8/E9 within the 3 bytes after one that was left as it is may be an operand byte, not an opcode:
 * `recent` holds a bit per byte back where one was left (bits 1-3), and where that one's top operand byte was
 * 00/FF (bits 5-7). Only the patterns the encoder converts after are converted, and where the value's byte that
 * the earlier opcode's operand would cover is 00/FF the encoder had flipped the bits below it: undone here. */
static void unfilter_x86(unsigned char *buf, size_t size)
{
    static const unsigned char allowed[8] = {1, 1, 1, 0, 1, 0, 0, 0}, byte_of[8] = {0, 1, 2, 2, 3, 3, 3, 3};
    uint32_t recent = 0;
    size_t last = 0;
    for (size_t i = 0; i + 5 <= size; ++i) {
        if (buf[i] != 0xE8 && buf[i] != 0xE9) continue;
        if (i - last > 5)
            recent = 0;
        else
            for (size_t k = i - last; k; --k) recent = (recent & 0x77) << 1;
        last = i;
        unsigned char top = buf[i + 4];
        int small = top == 0x00 || top == 0xFF;
        if (!small || !allowed[(recent >> 1) & 7] || (recent >> 1) >= 0x10) {
            recent |= 1u | (small ? 0x10u : 0u);
            continue;
        }
        uint32_t value = le32(buf + i + 1), relative;
        for (;;) {
            relative = value - (uint32_t)(i + 5);
            if (!recent) break;
            unsigned shift = 24 - 8 * byte_of[recent >> 1];
            unsigned char read = (unsigned char)(relative >> shift);
            if (read != 0x00 && read != 0xFF) break;
            value = relative ^ ((1u << shift << 8) - 1);
        }
        relative = (relative & 0x01FFFFFFu) | (relative & 0x01000000u ? 0xFE000000u : 0);
        put_le32(buf + i + 1, relative);
        recent = 0;
        i += 4;
    }
}

/* ARM64: the 26-bit word offset of BL, and the 21-bit page offset of ADRP where it is within +-2^17 pages (kept
 * as 18 bits, sign-extended), each made relative to the instruction's position again (a multiple of 4 in the tar,
 * whose files start at multiples of 512) */
static void unfilter_arm64(unsigned char *buf, size_t size)
{
    for (size_t at = 0; at + 4 <= size; at += 4) {
        uint32_t word = le32(buf + at), pc = (uint32_t)at;
        if ((word >> 26) == 0x25) { /* BL */
            put_le32(buf + at, 0x94000000u | ((word - (pc >> 2)) & 0x03FFFFFFu));
        } else if ((word & 0x9F000000u) == 0x90000000u) { /* ADRP */
            uint32_t pages = ((word >> 29) & 3) | ((word >> 3) & 0x001FFFFCu);
            if ((pages + 0x00020000u) & 0x001C0000u) continue;
            pages -= pc >> 12;
            word = (word & 0x9000001Fu) | (pages & 3) << 29 | (pages & 0x0003FFFCu) << 3 |
                   ((0u - (pages & 0x00020000u)) & 0x00E00000u);
            put_le32(buf + at, word);
        }
    }
}

/* ---- the cache folder ---- */

static char carried_folder[4096]; /* where this loader found or unpacked the archive ("" not yet) */

/* `path` joined with `name` (whose '/' become the system's separator) into `out`; 0 if it does not fit */
static int join(const char *path, const char *name, char *out, size_t size)
{
    int n = snprintf(out, size, "%s%c%s", path, SBF_SEPARATOR, name);
    if (n < 0 || (size_t)n >= size) return 0;
    for (char *c = out + strlen(path); *c; ++c)
        if (*c == '/') *c = SBF_SEPARATOR;
    return 1;
}

/* Whether `folder` holds every file of the archive with its size */
static int complete(const char *folder)
{
    char path[4096];
    for (size_t i = 0; carried_files[i].name; ++i)
        if (!join(folder, carried_files[i].name, path, sizeof path) || sbf_file_size(path) != carried_files[i].size)
            return 0;
    return carried_files[0].name != NULL;
}

/* Remove the archive's files and folders below `folder`, then `folder` (what is not there is skipped) */
static void remove_unpacked(const char *folder)
{
    char path[4096];
    for (size_t i = 0; carried_files[i].name; ++i) {
        if (!join(folder, carried_files[i].name, path, sizeof path)) continue;
        for (char *end; sbf_remove(path), (end = strrchr(path, SBF_SEPARATOR)) && (size_t)(end - path) > strlen(folder);)
            *end = '\0'; /* and the folders above it, up to `folder`, once empty */
    }
    sbf_remove(folder);
}

/* Make `path` and the folders above it; 0 with the system's reason in `why` */
static int make_folders(const char *path, char *why, size_t why_size)
{
    char partial[4096];
    snprintf(partial, sizeof partial, "%s", path);
    for (char *c = partial + 1; *c; ++c) {
        if (*c != '/' && *c != '\\') continue;
        char kept = *c;
        *c = '\0';
        if (c[-1] != ':') sbf_make_folder(partial, why, why_size); /* may exist, or be a drive */
        *c = kept;
    }
    return sbf_make_folder(partial, why, why_size);
}

/* The value of the tar header's octal field at `field` (`n` bytes) */
static long long octal(const unsigned char *field, size_t n)
{
    long long value = 0;
    for (size_t i = 0; i < n && field[i] >= '0' && field[i] <= '7'; ++i) value = value * 8 + (field[i] - '0');
    return value;
}

/* Write the files of the tar archive `tar` (`n` bytes) whose names start with `prefix` below `folder`, without that
 * prefix; 0 with why not */
static int write_tar(const unsigned char *tar, size_t n, const char *prefix, const char *folder, char *why,
                     size_t why_size)
{
    char name[256], path[4096], cause[512];
    for (size_t at = 0; at + 512 <= n && tar[at]; ) {
        const unsigned char *header = tar + at;
        long long size = octal(header + 124, 12);
        if (header[345])
            snprintf(name, sizeof name, "%.155s/%.100s", (const char *)header + 345, (const char *)header);
        else
            snprintf(name, sizeof name, "%.100s", (const char *)header);
        at += 512;
        if (size < 0 || (size_t)size > n - at || strstr(name, "..") || name[0] == '/')
            return snprintf(why, why_size, "the archive's entry %s is damaged", name), 0;
        if ((header[156] == '0' || header[156] == '\0') && strncmp(name, prefix, strlen(prefix)) == 0 &&
            join(folder, name + strlen(prefix), path, sizeof path)) {
            char *end = strrchr(path, SBF_SEPARATOR);
            *end = '\0';
            int made = make_folders(path, cause, sizeof cause);
            *end = SBF_SEPARATOR;
            if (!made || !sbf_write_file(path, tar + at, (size_t)size, cause, sizeof cause))
                return snprintf(why, why_size, "cannot write %s: %s", path, cause), 0;
        }
        at += ((size_t)size + 511) / 512 * 512;
    }
    return 1;
}

/* The folder the CPython is (to be) unpacked into, and the folder above it, into `folder` and `root`: the key's
 * folder in $SBF_PYTHON_CACHE or the user's cache, else "python" in this library's folder; 0 if it does not fit */
static int unpacked_folder(char *folder, char *root, size_t size)
{
    const char *named = getenv(CACHE_VARIABLE), *name = SBF_CARRIED_KEY;
    if (named && *named)
        snprintf(root, size, "%s", named);
    else if (!sbf_cache_root(root, size)) {
        char *end;
        if (!sbf_loader_path(root, size) || !(end = strrchr(root, SBF_SEPARATOR))) return 0;
        *end = '\0';
        name = CARRIED_PREFIX;
    }
    int n = snprintf(folder, size, "%s%c%s", root, SBF_SEPARATOR, name);
    return n > 0 && (size_t)n < size && strlen(root) + 1 < size;
}

/* The bytes (malloc'd) of the FMU's archive `name` and its size in *n; NULL with why not */
static unsigned char *read_pack(const char *name, size_t *n, char *why, size_t why_size)
{
    char self[4096], path[4096 + 256];
    if (!sbf_loader_path(self, sizeof self)) return snprintf(why, why_size, "cannot locate the FMU's binary"), NULL;
    char *end = NULL;
    for (int up = 0; up < 3; ++up) /* the FMU's root: the folder of binaries/<platform>/ */
        if ((end = strrchr(self, SBF_SEPARATOR))) *end = '\0';
    if (!end || !join(self, name, path, sizeof path))
        return snprintf(why, why_size, "cannot locate the FMU's root folder"), NULL;
    char cause[512];
    unsigned char *data = sbf_read_file(path, n, cause, sizeof cause);
    if (!data)
        snprintf(why, why_size, "its archive %s cannot be read (%s): extract the whole FMU, extra/ included", path,
                 cause);
    return data;
}

/* Write the files of the FMU's archive `name` (run through the branch filter `filter`, SBF_CARRIED_FILTER's numbers;
 * holding `size` bytes, 0 if unknown) whose names start with `prefix` below `folder`, without it; 0 with why not */
static int unpack_archive(const char *name, int filter, size_t size, const char *prefix, const char *folder,
                          char *why, size_t why_size)
{
    size_t n = 0;
    unsigned char *pack = read_pack(name, &n, why, why_size), *tar = NULL;
    char cause[1024];
    if (!pack) return 0;
    int ok = lzma_decode(pack, n, &tar, &size, cause, sizeof cause);
    free(pack);
    if (!ok) return snprintf(why, why_size, "its archive %s cannot be decoded: %s", name, cause), 0;
    if (filter == 1) unfilter_x86(tar, size);
    if (filter == 2) unfilter_arm64(tar, size);
    if (!(ok = write_tar(tar, size, prefix, folder, cause, sizeof cause))) snprintf(why, why_size, "%s", cause);
    free(tar);
    return ok;
}

/* Unpack the archives into `folder` through a folder of this thread's own beside it; 0 with why not */
static int unpack(const char *folder, char *why, size_t why_size)
{
    char part[4096 + 64], aside[4096 + 64], cause[1024];
    static int counter;
    snprintf(part, sizeof part, "%s.%s.part", folder, sbf_unique_name(++counter));
    snprintf(aside, sizeof aside, "%s.%s.old", folder, sbf_unique_name(counter));
    int ok = make_folders(part, cause, sizeof cause);
    if (!ok) snprintf(why, why_size, "%s", cause);
    ok = ok && unpack_archive(SBF_CARRIED_PACK, SBF_CARRIED_FILTER, SBF_CARRIED_TAR_SIZE, "", part, why, why_size);
    ok = ok && (!*SBF_CARRIED_SHARED_PACK ||
                unpack_archive(SBF_CARRIED_SHARED_PACK, 0, 0, SBF_CARRIED_SHARED_PREFIX, part, why, why_size));
    for (int attempt = 0; ok && attempt < 2; ++attempt) {
        int renamed = sbf_rename_folder(part, folder, cause, sizeof cause);
        if (renamed == 1) return 1;
        if (complete(folder)) break; /* another process or thread was first */
        if (renamed < 0 || attempt) {
            snprintf(why, why_size, "cannot rename %s to %s: %s", part, folder, cause);
            ok = 0;
        } else if (sbf_rename_folder(folder, aside, cause, sizeof cause) == 1) /* a damaged one in the way */
            remove_unpacked(aside);
    }
    remove_unpacked(part);
    return ok;
}

int sbf_carried_path(const char *relative, char *path, size_t size, char *why, size_t why_size)
{
    char root[4096], folder[4096], cause[2048] = "";
    if (!*carried_folder) {
        if (!unpacked_folder(folder, root, sizeof folder))
            return snprintf(why, why_size, "the CPython the FMU carries has no folder to be unpacked into (set %s)",
                            CACHE_VARIABLE), 0;
        if (!complete(folder)) {
            int made = make_folders(root, cause, sizeof cause), python = strcmp(relative, SBF_BUNDLED_INNER) != 0;
            if (!made || !unpack(folder, cause, sizeof cause))
                return snprintf(why, why_size, "the CPython the FMU carries cannot be unpacked into %s: %s%s. Set %s "
                                "to a folder where it can be (it takes %.0f MB)%s%s", folder,
                                made ? "" : "cannot make the folder: ", cause, CACHE_VARIABLE,
                                sbf_carried_bytes() / 1e6, python ? ", or " LIBPYTHON_VARIABLE : "",
                                python ? " to a CPython 3 shared library" : ""), 0;
        }
        snprintf(carried_folder, sizeof carried_folder, "%s", folder);
    }
    const char *rest = relative + strlen(CARRIED_PREFIX);
    if (strncmp(relative, CARRIED_PREFIX, strlen(CARRIED_PREFIX)) != 0 || (*rest != '/' && *rest != '\\') ||
        !join(carried_folder, rest + 1, path, size))
        return snprintf(why, why_size, "%s is no file of the CPython the FMU carries", relative), 0;
    return 1;
}

int sbf_carries_python(void) { return *SBF_CARRIED_PACK && carried_files[0].name; }

double sbf_carried_bytes(void)
{
    double total = 0;
    for (size_t i = 0; carried_files[i].name; ++i) total += (double)carried_files[i].size;
    return total;
}
