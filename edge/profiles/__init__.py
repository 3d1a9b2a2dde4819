"""Firmware profiles: ``firmware_profiles/<name>.toml`` -> typed, frozen, validated `Profile`.

API::

    load_profile(name_or_path="sim-dlp") -> Profile     # FileNotFoundError / ProfileError
    list_profiles() -> list[str]                         # names found on the search path
    profile_to_dict(profile) -> dict                     # JSON-able, nested like the TOML
    profile_from_dict(d, source="<dict>") -> Profile     # same validation as files
    apply_update(profile, partial_dict) -> Profile       # merged + validated; old one untouched
    changed_keys(old, new) -> list[str]                  # dotted keys that differ
    live_update(profile, partial) -> (Profile, changed)  # + the config-freeze policy (LIVE_TABLES)
    ConfigRejected(ValueError)                           # an update the running device refuses
    ProfileError(ValueError)                             # .source, .key (dotted), .reason

Access is by attribute: ``p.camera.rate_hz``, ``p.code.name``, ``p.geometry.doffs``,
``p.zenoh.key("depth") == "sl/sim-dlp/depth"``. The TOML layout and every constraint are in
`edge.profiles.settings`. Shipped profiles: sim-dlp (default), oak-d-pro, event-dots, light-curtain.
"""

from .files import (
    DEFAULT_PROFILE,
    apply_update,
    changed_keys,
    find_profile,
    list_profiles,
    load_profile,
    profile_dirs,
    profile_from_dict,
)
from .live import LIVE_TABLES, ConfigRejected, live_update
from .settings import (
    CameraSettings,
    CodeSettings,
    DecoderSettings,
    EdcSettings,
    GeometrySettings,
    Profile,
    ProfileError,
    ProjectorSettings,
    RecordingSettings,
    SensorSettings,
    SimSettings,
    ZenohSettings,
    profile_to_dict,
)

__all__ = [
    "DEFAULT_PROFILE",
    "LIVE_TABLES",
    "ConfigRejected",
    "live_update",
    "Profile",
    "ProfileError",
    "CameraSettings",
    "CodeSettings",
    "DecoderSettings",
    "EdcSettings",
    "GeometrySettings",
    "ProjectorSettings",
    "RecordingSettings",
    "SensorSettings",
    "SimSettings",
    "ZenohSettings",
    "apply_update",
    "changed_keys",
    "find_profile",
    "list_profiles",
    "load_profile",
    "profile_dirs",
    "profile_from_dict",
    "profile_to_dict",
]
