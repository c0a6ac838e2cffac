""""What happened" (sinks/summary.py): the findings it leaves to its own lines are the rules of the figures it
tells (the figure table's ``rules``), each a rule of the registry, whose name says the same thing."""

from __future__ import annotations

from rs30x_sniff.lint.registry import RULES
from rs30x_sniff.sinks.figures import FIGURES
from rs30x_sniff.sinks.summary import SWITCHED_BACK_ON, TOLD, TOLD_FIGURES


def test_the_told_rules_come_from_the_figure_table():
    assert TOLD == {code for name in TOLD_FIGURES for code in FIGURES[name].rules} | {SWITCHED_BACK_ON}
    # Every told figure names its rule: a figure without one would let its findings be told twice.
    assert all(FIGURES[name].rules for name in TOLD_FIGURES)


def test_each_told_rule_is_a_rule_of_the_registry_about_its_figure():
    for name in TOLD_FIGURES:
        for code in FIGURES[name].rules:
            rule = RULES.get(code)
            assert rule is not None and not rule.is_user, code
    names = {FIGURES[n].rules[0]: RULES.get(FIGURES[n].rules[0]).name for n in TOLD_FIGURES}
    # The flag figures' rules are the flags' own (rules/status.py), by name.
    for flag in ("temperature_limit", "temperature_alarm", "flash_write_error", "received_packet_error"):
        assert names[FIGURES[flag].rules[0]] == flag.replace("_", "-")
    assert RULES.get(SWITCHED_BACK_ON).name == "torque-on-after-temperature-limit"
