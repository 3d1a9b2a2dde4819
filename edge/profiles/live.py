"""Which settings may change while a device runs: the one config-freeze policy.

Both the zenoh config queryable (`edge.io.zenoh.DepthPublisher`) and the service
(`edge.runtime.service.Service.update_config`) apply a partial update through `live_update`,
so they accept and refuse the same updates with the same reasons.
"""

from __future__ import annotations

from typing import Any, Mapping

from .files import apply_update, changed_keys
from .settings import Profile

#: Profile tables that may change while the service runs (applied between stacks).  Everything
#: else (camera, projector, code, zenoh, name...) needs a restart with another profile.
LIVE_TABLES = ("decoder", "edc", "geometry", "oak")


class ConfigRejected(ValueError):
    """A config update the running device refuses (or a config query that failed); the message is the reason."""


def frozen_keys(changed: list[str]) -> list[str]:
    """The dotted keys of ``changed`` outside `LIVE_TABLES`."""
    return [k for k in changed if k.split(".")[0] not in LIVE_TABLES]


def live_update(profile: Profile, update: Mapping[str, Any], *, source: str = "config update") -> tuple[Profile, list[str]]:
    """Validate ``update`` against ``profile`` -> (new profile, changed dotted keys).

    Raises `edge.profiles.ProfileError` for an invalid value and `ConfigRejected` when a key
    outside `LIVE_TABLES` would change (both ValueError); ``profile`` is never modified.
    """
    new = apply_update(profile, update, source=source)
    changed = changed_keys(profile, new)
    frozen = frozen_keys(changed)
    if frozen:
        tables = list(dict.fromkeys(k.split(".")[0] for k in frozen))
        raise ConfigRejected(
            f"{', '.join(tables)} cannot change while running ({', '.join(frozen)}; live tables: "
            f"{', '.join(LIVE_TABLES)}; restart with another profile)")
    return new, changed
