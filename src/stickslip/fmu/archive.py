"""The FMUs' zip archives, written reproducibly: the same entries give the same bytes.

Entries are written in the order of their names, each with one date and time (:func:`source_date`, else
1980-01-01 00:00, the earliest a zip entry can hold), the Unix permissions ``rw-r--r--`` and deflate at zlib's
highest level (:data:`DEFLATE_LEVEL`), except what is compressed already (:data:`STORED_SUFFIXES`): the zip
archives of Python code, whose files are deflated one by one (zipimport inflates only the byte code it imports;
storing them and deflating each archive whole would take 0.03 MB off the FMU and add 1.3-1.6 ms to each of FMPy's
runs of it), and the packed CPythons (:mod:`stickslip.fmu.bundle.packing`), which are stored. The Linux
shared libraries are deflated too (the compiled runtime 1.20 MB to 0.44 MB, the FMI library's binary 0.37 to 0.11
MB): hosts inflate them when they extract the FMU, the 1.84 MB of the x86_64 Linux ones in 5 ms, and the FMU
without its carried CPythons pays that too (benchmarks/README.md, "What the carried CPython costs").
:func:`identity` names one build of an FMU in its model description.
"""

import datetime
import os
import re
import uuid
import zipfile

#: the variable of reproducible builds: the date to stamp, in seconds since 1970-01-01 00:00 UTC
SOURCE_DATE_VARIABLE = "SOURCE_DATE_EPOCH"
#: the entries' date and time without ``$SOURCE_DATE_EPOCH`` (zip's epoch)
ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
#: the entries' Unix file type and permissions: a regular file, rw-r--r--
FILE_MODE = 0o100644
#: the entries stored without compression: compressed already (zip archives, LZMA-packed CPythons)
STORED_SUFFIXES = (".zip", ".lzma")
#: zlib's level of the deflated entries: 9, the smallest (0.3 % smaller than the default 6; inflating is as fast)
DEFLATE_LEVEL = 9
#: the name of a Linux shared library, with or without a version after ``.so``
SHARED_LIBRARY = re.compile(r".*\.so(\.\d+)*")
#: the namespace of the FMUs' GUIDs (uuid5 of the model name, the FMI version and the source tag)
GUID_NAMESPACE = uuid.uuid5(uuid.NAMESPACE_URL, "stickslip:fmu")


def source_date():
    """``$SOURCE_DATE_EPOCH`` as an aware UTC datetime, or None if it is not set."""
    seconds = os.environ.get(SOURCE_DATE_VARIABLE)
    return datetime.datetime.fromtimestamp(int(seconds), datetime.timezone.utc) if seconds else None


def identity(model_name, fmi_version, tag):
    """``(guid, generation date)`` for the model description of an FMU built from the sources of ``tag``: the GUID
    (FMI 3: instantiation token) follows from the sources alone; the date is :func:`source_date` as ISO 8601 text,
    or None (left out)."""
    guid = uuid.uuid5(GUID_NAMESPACE, f"{model_name}:fmi{fmi_version}:{tag}")
    date = source_date()
    return str(guid), None if date is None else date.isoformat(timespec="seconds")


def read_entries(path):
    """The files of the zip archive at ``path``: ``{name: bytes}`` (folder entries left out)."""
    with zipfile.ZipFile(path) as archive:
        return {item.filename: archive.read(item) for item in archive.infolist() if not item.is_dir()}


def write_entries(path, entries, deflate=True):
    """Write ``entries`` (``{name: bytes}``) as a new zip archive at ``path`` (or into a binary file object),
    reproducibly (see the module); ``deflate``: False stores every entry (for a zip that is compressed whole)."""
    date = source_date()
    stamp = ZIP_EPOCH if date is None else max(ZIP_EPOCH, date.timetuple()[:6])
    with zipfile.ZipFile(path, "w") as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, stamp)
            info.create_system = 3  # Unix, so that hosts read external_attr as Unix permissions
            info.external_attr = FILE_MODE << 16
            deflated = deflate and not name.endswith(STORED_SUFFIXES)
            info.compress_type = zipfile.ZIP_DEFLATED if deflated else zipfile.ZIP_STORED
            archive.writestr(info, entries[name], compresslevel=DEFLATE_LEVEL if deflated else None)
