"""The named field positions of events and the named byte positions of a frame agree with what they name."""

from rs30x_sniff.protocol import events as E
from rs30x_sniff.protocol import wire as W
from rs30x_sniff.decode.framing import FrameDecoder


def test_field_positions_are_the_classes_fields():
    for cls, names in (
        (E.ShortPacket, ("OFFSET", "RAW", "T_START", "T_END", "ID", "FLAG", "ADDRESS", "LENGTH", "COUNT", "DATA",
                         "CHECKSUM_OK")),
        (E.ReturnPacket, ("OFFSET", "RAW", "T_START", "T_END", "ID", "FLAG", "ADDRESS", "LENGTH", "COUNT", "DATA",
                          "CHECKSUM_OK")),
        (E.LongPacket, ("OFFSET", "RAW", "T_START", "T_END", "LONG_FLAG", "LONG_ADDRESS", "LONG_LENGTH",
                        "LONG_COUNT", "LONG_RECORDS", "LONG_CHECKSUM_OK")),
        (E.Garbage, ("OFFSET", "RAW", "T_START", "T_END", "REASON")),
    ):
        assert [getattr(E, n) for n in names] == list(range(len(cls._fields)))
        # the field each position names (FLAG is a return packet's "flags")
        for n, field in zip(names, cls._fields):
            assert n.removeprefix("LONG_").lower() in (field, field.rstrip("s")), (cls, n, field)


def test_frame_byte_positions_match_the_encoders():
    short = W.encode_short(3, 0x0F, 0x1E, b"\x01\x02")
    ret = W.encode_return(4, 0x2A, b"\x09\x08\x07", flags=W.RETURN_TEMPERATURE_ALARM)
    long_ = W.encode_long(0x1E, [(1, b"\x10\x00"), (2, b"\x20\x00")])
    assert (short[W.AT_ID], short[W.AT_FLAG], short[W.AT_ADDRESS], short[W.AT_LENGTH], short[W.AT_COUNT]) == (
        3, 0x0F, 0x1E, 2, 1)
    assert short[W.AT_DATA:-W.SUM_SIZE] == b"\x01\x02"
    assert len(short) == 2 + W.FRAME_OVERHEAD
    assert short[0] == W.REQUEST_FIRST and ret[0] == W.RETURN_FIRST
    assert (ret[W.AT_ID], ret[W.AT_FLAG], ret[W.AT_ADDRESS], ret[W.AT_LENGTH]) == (
        4, W.RETURN_TEMPERATURE_ALARM, 0x2A, 3)
    assert long_[W.AT_ID] == W.LONG_PACKET_ID and long_[W.AT_COUNT] == 2

    ev_short, ev_ret, ev_long = FrameDecoder(115200).feed(short + ret + long_, None)
    assert ev_short[E.ID] == 3 and ev_short[E.FLAG] == 0x0F and ev_short[E.DATA] == b"\x01\x02"
    assert ev_ret[E.ID] == 4 and ev_ret[E.ADDRESS] == 0x2A and ev_ret[E.CHECKSUM_OK]
    assert ev_long[E.LONG_ADDRESS] == 0x1E and ev_long[E.LONG_COUNT] == 2 and len(ev_long[E.LONG_RECORDS]) == 2
