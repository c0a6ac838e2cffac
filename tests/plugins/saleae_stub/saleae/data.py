"""Stand-ins for ``saleae.data``: GraphTime (a point in time) and GraphTimeDelta (a duration), as Logic 2 documents
them: a time minus a time is a delta, a time plus or minus a delta is a time, a delta converts to float seconds."""

from fractions import Fraction


class GraphTimeDelta:
    def __init__(self, second=0):
        self.seconds = Fraction(second)

    def __float__(self):
        return float(self.seconds)

    def __add__(self, other):
        return GraphTimeDelta(self.seconds + other.seconds)

    def __sub__(self, other):
        return GraphTimeDelta(self.seconds - other.seconds)

    def __eq__(self, other):
        return isinstance(other, GraphTimeDelta) and self.seconds == other.seconds

    def __lt__(self, other):
        return self.seconds < other.seconds

    def __repr__(self):
        return f"GraphTimeDelta({float(self.seconds)!r})"


class GraphTime:
    """Seconds from an arbitrary origin, exactly (a Fraction): no float of its own to compare by mistake."""

    def __init__(self, seconds):
        self._s = Fraction(seconds)

    def __sub__(self, other):
        if isinstance(other, GraphTime):
            return GraphTimeDelta(self._s - other._s)
        if isinstance(other, GraphTimeDelta):
            return GraphTime(self._s - other.seconds)
        return NotImplemented

    def __add__(self, other):
        if isinstance(other, GraphTimeDelta):
            return GraphTime(self._s + other.seconds)
        return NotImplemented

    def __eq__(self, other):
        return isinstance(other, GraphTime) and self._s == other._s

    def __hash__(self):
        return hash(self._s)

    def __repr__(self):
        return f"GraphTime({float(self._s)!r})"


SaleaeTime = GraphTime
