"""Exception types. Every problem a user can cause raises a subclass of :class:`GMWMError`
with a one-line message naming the problem; the CLI prints it without a traceback."""


class GMWMError(ValueError):
    """Base class for user-facing errors (bad input, bad model, bad file layout)."""


class InputError(GMWMError):
    """Signal or table unusable: NaN/inf, too short for the requested scales, wrong layout."""


class ModelError(GMWMError):
    """Unknown process, malformed model string, unknown or missing parameter."""


class IdentifiabilityError(GMWMError):
    """The request cannot be identified, e.g. more parameters than wavelet scales."""


class DataUnavailableError(GMWMError):
    """A real-data file is neither present locally nor obtainable from its public source."""
