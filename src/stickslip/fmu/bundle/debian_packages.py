"""Debian 12's arm64 packages of the CPython the FMUs carry for aarch64 Linux hosts, fetched with apt.

apt-get runs with a configuration of its own (:func:`apt_options`: its package lists, cache and sources in
:data:`CACHE`, the architecture arm64, nothing of the system's state or sources), so that it needs neither root nor
a system set up for arm64, and checks what it downloads against Debian's signed release files with the system's
Debian archive keyring. Each package is unpacked once into ``CACHE/root`` (:func:`arm64_root`), which then holds
the files under their paths on an arm64 Debian machine. Where apt-get, the keyring or the network is missing, the
caller gets why, and the build leaves the platform out.
"""

import functools
import io
import os
import shutil
import subprocess
import tarfile
from pathlib import Path

from ..compile_runtime import USER_CACHE

#: where apt's state, the downloaded packages and their unpacked files are kept
CACHE = USER_CACHE / "debian-arm64"
#: the variable naming another Debian mirror (default :data:`MIRROR`)
MIRROR_VARIABLE, MIRROR = "SBF_DEBIAN_MIRROR", "http://deb.debian.org"
#: the keyring Debian's release files are signed with (Debian's package debian-archive-keyring)
KEYRING = Path("/usr/share/keyrings/debian-archive-keyring.gpg")
#: the suites searched: Debian 12 with its updates and security updates (the newest version of each package wins)
SUITES = (("debian", "bookworm"), ("debian", "bookworm-updates"), ("debian-security", "bookworm-security"))
#: the packages the carried CPython is made of: the interpreter's shared library and standard library, and the
#: libraries that it and the extension modules the FMU carries need that are not glibc's
PACKAGES = ("libpython3.11", "libpython3.11-minimal", "libpython3.11-stdlib", "zlib1g", "libexpat1", "libffi8",
            "libuuid1")
#: a file in the unpacked tree that marks it complete
COMPLETE = "complete"
#: tarfile's extraction that refuses members outside the folder and device files (CPython 3.11.4 and newer)
SAFE_EXTRACTION = {"filter": "tar"} if hasattr(tarfile, "tar_filter") else {}


def apt_options(folder):
    """The ``-o`` options that make apt-get work on arm64 packages in ``folder`` alone."""
    options = {"Dir::Etc::SourceList": folder / "sources.list", "Dir::Etc::SourceParts": folder / "sources.list.d",
               "Dir::State": folder / "state", "Dir::State::status": os.devnull, "Dir::Cache": folder / "cache",
               "APT::Architecture": "arm64", "APT::Architectures::": "arm64", "Debug::NoLocking": "1",
               "Acquire::Retries": "1", "Acquire::http::Timeout": "30"}
    if os.geteuid() == 0:  # apt's download user could not write into the user's cache folder
        options["APT::Sandbox::User"] = "root"
    return [item for key, value in options.items() for item in ("-o", f"{key}={value}")]


def _sources(mirror):
    """The text of apt's sources.list for :data:`SUITES` on ``mirror``."""
    return "".join(f"deb [arch=arm64 signed-by={KEYRING}] {mirror}/{archive} {suite} main\n"
                   for archive, suite in SUITES)


def _apt(folder, *arguments, cwd=None):
    """Run apt-get with :func:`apt_options` of ``folder``; None, or why it failed."""
    try:
        run = subprocess.run(["apt-get", "-q", *apt_options(folder), *arguments], capture_output=True, text=True,
                             timeout=900, cwd=cwd)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"apt-get {arguments[0]} failed: {exc}"
    return None if run.returncode == 0 else f"apt-get {arguments[0]} failed: {run.stderr.strip()[-500:]}"


def download(folder=CACHE):
    """Download :data:`PACKAGES` (arm64) into ``folder/debs`` unless they are there: ``(their paths, None)``, or
    ``(None, why not)``."""
    debs = folder / "debs"
    found = sorted(debs.glob("*_arm64.deb")) if debs.is_dir() else []
    if {path.name.split("_", 1)[0] for path in found} >= set(PACKAGES):
        return found, None
    if shutil.which("apt-get") is None:
        return None, "apt-get is not installed (a Debian or Ubuntu machine fetches Debian's arm64 packages)"
    if not KEYRING.is_file():
        return None, f"Debian's archive keyring {KEYRING} is missing (Debian's package debian-archive-keyring)"
    for sub in ("state/lists/partial", "cache/archives/partial", "sources.list.d", "debs"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    (folder / "sources.list").write_text(_sources(os.environ.get(MIRROR_VARIABLE) or MIRROR))
    why = _apt(folder, "update") or _apt(folder, "download", *(f"{name}:arm64" for name in PACKAGES), cwd=debs)
    if why:
        return None, why
    return sorted(debs.glob("*_arm64.deb")), None


def deb_members(path):
    """``{member name: bytes}`` of the ar archive of the Debian package at ``path``."""
    data, members, at = Path(path).read_bytes(), {}, 8
    if not data.startswith(b"!<arch>\n"):
        raise ValueError(f"{path} is no Debian package (no ar archive)")
    while at + 60 <= len(data):
        name, size = data[at:at + 16].decode().strip().rstrip("/"), int(data[at + 48:at + 58])
        members[name] = data[at + 60:at + 60 + size]
        at += 60 + size + size % 2
    return members


def unpack(deb, root):
    """Unpack the files of the Debian package ``deb`` (a path) below ``root``, as dpkg would (links as links)."""
    member = next(name for name in deb_members(deb) if name.startswith("data.tar"))
    with tarfile.open(fileobj=io.BytesIO(deb_members(deb)[member])) as data:
        data.extractall(root, **SAFE_EXTRACTION)


@functools.cache
def arm64_root(folder=CACHE):
    """``(the folder holding the packages' files, None)``, downloading and unpacking them once, or ``(None, why
    not)``; once per process."""
    root = folder / "root"
    if (root / COMPLETE).is_file():
        return root, None
    debs, why = download(folder)
    if debs is None:
        return None, why
    partial = folder / f"root.{os.getpid()}.part"
    shutil.rmtree(partial, ignore_errors=True)
    for deb in debs:
        unpack(deb, partial)
    (partial / COMPLETE).write_text("".join(f"{deb.name}\n" for deb in debs))
    replace_folder(partial, root)
    return root, None


def replace_folder(partial, folder):
    """Move the folder ``partial`` to ``folder``, unless another process has made ``folder`` meanwhile (its copy is
    then dropped)."""
    try:
        os.replace(partial, folder)
    except OSError:
        if not folder.is_dir():
            raise
        shutil.rmtree(partial, ignore_errors=True)
