"""Stand-in for ``saleae.analyzers``: the classes a High Level Analyzer imports, as Saleae's API documentation gives
them (HighLevelAnalyzer, AnalyzerFrame, StringSetting, NumberSetting, ChoicesSetting)."""

from .data import GraphTime

# What Logic 2 takes as an AnalyzerFrame's data values.
DATA_TYPES = (str, int, float, bool, bytes)


class AnalyzerFrame:
    def __init__(self, type, start_time, end_time, data=None):
        self.type = type
        self.start_time = start_time
        self.end_time = end_time
        self.data = dict(data or {})

    def __repr__(self):
        return f"AnalyzerFrame({self.type!r}, {self.start_time!r}, {self.end_time!r}, {self.data!r})"


class Setting:
    def __init__(self, label=None):
        self.label = label


class StringSetting(Setting):
    pass


class NumberSetting(Setting):
    def __init__(self, *, min_value=None, max_value=None, **kwargs):
        super().__init__(**kwargs)
        self.min_value = min_value
        self.max_value = max_value


class ChoicesSetting(Setting):
    def __init__(self, choices, **kwargs):
        super().__init__(**kwargs)
        self.choices = tuple(choices)


class HighLevelAnalyzer:
    """Logic 2 sets each setting's value on the instance before it calls ``__init__``: :func:`make` does that."""

    def decode(self, frame):
        raise NotImplementedError


def make(cls, **settings):
    """An analyzer instance as Logic 2 makes one: settings (checked against their declarations) then __init__."""
    hla = cls.__new__(cls)
    for name, value in settings.items():
        decl = getattr(cls, name)
        if isinstance(decl, ChoicesSetting):
            assert value in decl.choices, (name, value)
        elif isinstance(decl, NumberSetting):
            assert (decl.min_value is None or value >= decl.min_value) and \
                   (decl.max_value is None or value <= decl.max_value), (name, value)
        setattr(hla, name, value)
    hla.__init__()
    return hla


__all__ = ["AnalyzerFrame", "ChoicesSetting", "GraphTime", "HighLevelAnalyzer", "NumberSetting", "StringSetting",
           "make"]
