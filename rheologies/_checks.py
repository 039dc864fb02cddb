"""Parameter checks shared by the built-in laws (raise ValueError: reported as exit 2)."""


def non_negative(**values: float) -> None:
    """Raise ValueError naming the first parameter that is negative (or nan)."""
    for key, value in values.items():
        if not value >= 0:
            raise ValueError(f"{key} must be >= 0, got {value!r}")


def positive(**values: float) -> None:
    """Raise ValueError naming the first parameter that is not > 0."""
    for key, value in values.items():
        if not value > 0:
            raise ValueError(f"{key} must be > 0, got {value!r}")
