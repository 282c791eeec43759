"""The CPythons the FMUs carry for hosts without one, and the binaries that go with them, per platform."""
