"""The physics every layer above shares: units and reference conditions, ISO 6358 flow
(D2), cylinder volumes (D1), the chambers of a drive (D4), stroke times, and the flow
meter's response. Pure functions and small integrators; nothing here reads files or knows
the machine file's format beyond the attributes a consumer has."""
