#!/usr/bin/env python3
"""One-off conversion of the stitch-by-stitch uniaxial measurements (HDF5) to small CSV files.

Source: github.com/sabetta/stitch-by-stitch (MIT licence, (c) 2023 sabetta), the data of
K. Singal, M. S. Dimitriyev, S. E. Gonzalez, A. P. Cachine, S. Quinn, E. A. Matsumoto,
"Programming mechanics in knitted materials, stitch by stitch", Nature Communications 15, 2622 (2024).
Files: data/uniaxial_experiments/experimentData/outputData_<sample>.h5.

The file format (data/uniaxial_experiments/experimentData/README.md): per video k = 1..5,
/videok/frames, /videok/traj (pins x frame, written by MATLAB as [frames 2 pins]) and
/videok/forces (force gauge, N); /clampSize (pixels across the clamp, which is 35.5 mm:
`clampSizeInPhysicalUnits = 35.5` in template.nb) and /fabricSize (fabric width at the clamp, pixels).
Pins: 1 right, 2 left, 3 bottom, 4 top, 5 bottom clamp, 6 top clamp.

What this writes (the reduction of the repository's template.nb, then binned): for videos 2..5 (template.nb
skips video 1), the clamp-to-clamp distance L (pins 5, 6) in mm, the extension L - L0 with L0 the clamp
distance in the first kept frame of video 2 (as template.nb), and the force in N; then the loading curve
in 24 equal extension bins from 0 to the smallest largest extension of the videos: per bin the mean force
of each video, and their mean, least and greatest. Header lines `# fabric_width_mm` (the fabric width at
the clamp) and `# clamp_distance_mm` (L0) give the sample's geometry.

Usage: python3 tools/stitch_by_stitch_to_csv.py <dir with the .h5 files> <out dir>
The .h5 files come from the repository, e.g.
  git clone https://github.com/sabetta/stitch-by-stitch && ls stitch-by-stitch/data/uniaxial_experiments/experimentData
This script needs only the Python standard library: it reads the subset of HDF5 that MATLAB's
h5create/h5write produce (superblock 0, symbol-table groups, version-1 object headers, chunked
little-endian float64 datasets indexed by version-1 B-trees, optional deflate).
"""

import os
import struct
import sys
import zlib

CLAMP_MM = 35.5


class H5:
    def __init__(self, path):
        with open(path, "rb") as f:
            self.b = f.read()
        if self.b[:8] != b"\x89HDF\r\n\x1a\n":
            raise ValueError(f"{path}: not an HDF5 file")
        if self.b[8] != 0:
            raise ValueError(f"{path}: superblock version {self.b[8]} (only 0 is read)")
        if self.b[13] != 8 or self.b[14] != 8:
            raise ValueError(f"{path}: offsets/lengths are not 8 bytes")
        root_header = self.u64(56 + 8)
        self.root = root_header

    def u8(self, o):
        return self.b[o]

    def u16(self, o):
        return struct.unpack_from("<H", self.b, o)[0]

    def u32(self, o):
        return struct.unpack_from("<I", self.b, o)[0]

    def u64(self, o):
        return struct.unpack_from("<Q", self.b, o)[0]

    def messages(self, addr):
        """(type, body offset, size) of every message of a version-1 object header."""
        if self.u8(addr) != 1:
            raise ValueError(f"object header version {self.u8(addr)} at {addr} (only 1 is read)")
        n = self.u16(addr + 2)
        size = self.u32(addr + 8)
        blocks = [(addr + 16, size)]
        out = []
        while blocks and len(out) < n:
            start, length = blocks.pop(0)
            o = start
            while o + 8 <= start + length and len(out) < n:
                mtype = self.u16(o)
                msize = self.u16(o + 2)
                body = o + 8
                out.append((mtype, body, msize))
                if mtype == 0x10:
                    blocks.append((self.u64(body), self.u64(body + 8)))
                o = body + msize
        return out

    def group(self, addr):
        """name -> object header address of a group (symbol table or compact link messages)."""
        links = {}
        for mtype, body, _ in self.messages(addr):
            if mtype == 0x11:
                btree, heap = self.u64(body), self.u64(body + 8)
                return self._btree_group(btree, self._heap_data(heap))
            if mtype == 0x06:
                name, target = self._link(body)
                links[name] = target
        if not links:
            raise ValueError(f"object at {addr} is not a group")
        return links

    def _link(self, body):
        """A hard link message (version 1): (name, object header address)."""
        if self.u8(body) != 1:
            raise ValueError("link message version")
        flags = self.u8(body + 1)
        o = body + 2
        if flags & 0x08:
            if self.u8(o) != 0:
                raise ValueError("only hard links are read")
            o += 1
        if flags & 0x04:
            o += 8
        if flags & 0x10:
            o += 1
        width = 1 << (flags & 0x03)
        n = int.from_bytes(self.b[o:o + width], "little")
        o += width
        name = self.b[o:o + n].decode()
        return name, self.u64(o + n)

    def _heap_data(self, heap):
        if self.b[heap:heap + 4] != b"HEAP":
            raise ValueError("local heap signature")
        return self.u64(heap + 24)

    def _name(self, heap_data, off):
        s = heap_data + off
        e = self.b.index(b"\0", s)
        return self.b[s:e].decode()

    def _btree_group(self, node, heap_data):
        if self.b[node:node + 4] != b"TREE":
            raise ValueError("B-tree signature")
        level = self.u8(node + 5)
        used = self.u16(node + 6)
        o = node + 24
        out = {}
        for i in range(used):
            child = self.u64(o + 8 + i * 16)
            if level > 0:
                out.update(self._btree_group(child, heap_data))
            else:
                out.update(self._snod(child, heap_data))
        return out

    def _snod(self, addr, heap_data):
        if self.b[addr:addr + 4] != b"SNOD":
            raise ValueError("symbol node signature")
        n = self.u16(addr + 6)
        out = {}
        for i in range(n):
            e = addr + 8 + 40 * i
            out[self._name(heap_data, self.u64(e))] = self.u64(e + 8)
        return out

    def dataset(self, addr):
        """(dims, flat list of float64 in C order) of a float64 dataset."""
        dims = None
        layout = None
        filters = []
        for mtype, body, _ in self.messages(addr):
            if mtype == 0x01:
                ver = self.u8(body)
                rank = self.u8(body + 1)
                off = body + (8 if ver == 1 else 4)
                dims = [self.u64(off + 8 * i) for i in range(rank)]
            elif mtype == 0x03:
                cls = self.u8(body) & 0x0F
                size = self.u32(body + 4)
                bits = self.u8(body + 1)
                if cls != 1 or size != 8 or bits & 1:
                    raise ValueError("dataset is not little-endian float64")
            elif mtype == 0x08:
                layout = body
            elif mtype == 0x0B:
                ver = self.u8(body)
                nf = self.u8(body + 1)
                o = body + (8 if ver == 1 else 2)
                for _ in range(nf):
                    fid = self.u16(o)
                    if ver == 1 or fid >= 256:
                        nlen = self.u16(o + 2)
                    else:
                        nlen = 0
                    ncv = self.u16(o + 6) if ver == 1 or fid >= 256 else self.u16(o + 4)
                    head = 8 if (ver == 1 or fid >= 256) else 6
                    nlen_p = (nlen + 7) // 8 * 8 if ver == 1 else nlen
                    o += head + nlen_p + 4 * ncv
                    if ver == 1 and ncv % 2:
                        o += 4
                    filters.append(fid)
        if dims is None or layout is None:
            raise ValueError(f"object at {addr} is not a dataset")
        for fid in filters:
            if fid != 1:
                raise ValueError(f"filter {fid} is not supported (deflate only)")
        total = 1
        for d in dims:
            total *= d
        if self.u8(layout) != 3:
            raise ValueError("layout message version is not 3")
        cls = self.u8(layout + 1)
        if cls == 1:
            a = self.u64(layout + 2)
            return dims, list(struct.unpack_from(f"<{total}d", self.b, a))
        if cls != 2:
            raise ValueError(f"layout class {cls} is not supported")
        rank1 = self.u8(layout + 2)
        btree = self.u64(layout + 3)
        chunk = [self.u32(layout + 11 + 4 * i) for i in range(rank1 - 1)]
        out = [float("nan")] * total
        for offs, caddr, csize in self._chunks(btree, rank1):
            raw = self.b[caddr:caddr + csize]
            if filters:
                raw = zlib.decompress(raw)
            vals = struct.unpack_from(f"<{len(raw) // 8}d", raw, 0)
            # scatter the chunk (C order within the chunk) into the array
            cstr = [1] * len(chunk)
            for i in range(len(chunk) - 2, -1, -1):
                cstr[i] = cstr[i + 1] * chunk[i + 1]
            dstr = [1] * len(dims)
            for i in range(len(dims) - 2, -1, -1):
                dstr[i] = dstr[i + 1] * dims[i + 1]
            for k, v in enumerate(vals):
                idx = 0
                ok = True
                for i in range(len(chunk)):
                    c = (k // cstr[i]) % chunk[i] + offs[i]
                    if c >= dims[i]:
                        ok = False
                        break
                    idx += c * dstr[i]
                if ok:
                    out[idx] = v
        return dims, out

    def _chunks(self, node, rank1):
        if self.b[node:node + 4] != b"TREE":
            raise ValueError("chunk B-tree signature")
        level = self.u8(node + 5)
        used = self.u16(node + 6)
        key = 8 + 8 * rank1
        o = node + 24
        for i in range(used):
            k = o + i * (key + 8)
            csize = self.u32(k)
            offs = [self.u64(k + 8 + 8 * j) for j in range(rank1 - 1)]
            child = self.u64(k + key)
            if level > 0:
                yield from self._chunks(child, rank1)
            else:
                yield offs, child, csize


BINS = 24


def convert(path, out):
    """Reads one sample's file and writes its mean loading curve; returns (width mm, L0 mm, rows)."""
    h = H5(path)
    root = h.group(h.root)
    clamp_px = h.dataset(root["clampSize"])[1][0]
    fabric_px = h.dataset(root["fabricSize"])[1][0]
    mm_per_px = CLAMP_MM / clamp_px
    videos = []
    l0 = None
    for k in range(2, 6):
        name = f"video{k}"
        if name not in root:
            continue
        g = h.group(root[name])
        (pins, _, n), traj = h.dataset(g["traj"])
        _, forces = h.dataset(g["forces"])
        if pins < 6:
            raise ValueError(f"{path}: {name} has {pins} pins, no clamp markers")

        def at(p, c, i):
            return traj[(p * 2 + c) * n + i]

        pts = []
        for i in range(n):
            dx = at(4, 0, i) - at(5, 0, i)
            dy = at(4, 1, i) - at(5, 1, i)
            length = (dx * dx + dy * dy) ** 0.5 * mm_per_px
            if l0 is None:
                l0 = length
            pts.append((length - l0, forces[i]))
        videos.append((k, pts))
    # Bins of equal width up to the smallest largest extension over the videos, so that every video
    # contributes to every bin; per bin the mean force of each video, then the mean over the videos.
    top = min(max(e for e, _ in pts) for _, pts in videos)
    width = top / BINS
    rows = []
    for b in range(BINS):
        lo, hi = b * width, (b + 1) * width
        per_video = []
        for _, pts in videos:
            f = [fo for e, fo in pts if lo <= e < hi]
            if f:
                per_video.append(sum(f) / len(f))
        if not per_video:
            continue
        mean = sum(per_video) / len(per_video)
        rows.append(((lo + hi) / 2, mean, min(per_video), max(per_video), len(per_video)))
    with open(out, "w") as f:
        f.write("# Singal et al., Nat. Commun. 15, 2622 (2024); github.com/sabetta/stitch-by-stitch (MIT)\n")
        f.write(f"# source: {os.path.basename(path)}; videos 2-5 (as template.nb); clamp 35.5 mm = {clamp_px:.3f} px\n")
        f.write(f"# fabric_width_mm {fabric_px * mm_per_px:.3f}\n")
        f.write(f"# clamp_distance_mm {l0:.3f}\n")
        f.write("extension_mm,force_n,force_min_n,force_max_n,videos\n")
        for e, m, lo, hi, nv in rows:
            f.write(f"{e:.3f},{m:.3f},{lo:.3f},{hi:.3f},{nv}\n")
    return fabric_px * mm_per_px, l0, len(rows)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: stitch_by_stitch_to_csv.py <h5 dir> <out dir>")
    src, dst = sys.argv[1], sys.argv[2]
    os.makedirs(dst, exist_ok=True)
    for knit in ("Stockinette", "Rib"):
        for d in ("X", "Y"):
            name = f"outputData_Acrylic Yarn {knit} {d}.h5"
            out = os.path.join(dst, f"acrylic_{knit.lower()}_{d.lower()}.csv")
            w, l0, n = convert(os.path.join(src, name), out)
            print(f"{out}: width {w:.2f} mm, clamp distance {l0:.2f} mm, {n} rows")


if __name__ == "__main__":
    main()
