"""Numbers written in words, for the grown-up check (:class:`app.story.GrownUpQuestion`).

A grown-up reads the number and types its digits; a child who cannot yet read large
numbers cannot. English follows the US style without "and" ("four hundred seventy-two
thousand, six hundred nineteen"); Japanese uses kanji numerals with 万 grouping
(四十七万二千六百十九), as a teacher reads them on a cheque or a form.
"""
from __future__ import annotations

_ONES = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven",
         "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen", "eighteen", "nineteen")
_TENS = ("", "", "twenty", "thirty", "forty", "fifty", "sixty", "seventy", "eighty", "ninety")
_KANJI_DIGITS = "〇一二三四五六七八九"

#: The largest number written (the grown-up check's are six digits).
MAX_NUMBER = 999_999_999


def _english_below_1000(n: int) -> str:
    words = []
    if n >= 100:
        words.append(f"{_ONES[n // 100]} hundred")
        n %= 100
    if n >= 20:
        words.append(_TENS[n // 10] + (f"-{_ONES[n % 10]}" if n % 10 else ""))
    elif n > 0 or not words:
        words.append(_ONES[n])
    return " ".join(words)


def english(n: int) -> str:
    """``n`` (0 to :data:`MAX_NUMBER`) in English words: 472619 -> "four hundred seventy-two
    thousand, six hundred nineteen"."""
    if not 0 <= n <= MAX_NUMBER:
        raise ValueError(f"{n} is outside 0-{MAX_NUMBER}")
    if n == 0:
        return _ONES[0]
    groups = []
    for scale, name in ((1_000_000, "million"), (1_000, "thousand"), (1, "")):
        part, n = divmod(n, scale)
        if part:
            groups.append(_english_below_1000(part) + (f" {name}" if name else ""))
    return ", ".join(groups)


def _kanji_below_10000(n: int) -> str:
    out = []
    for value, unit in ((1000, "千"), (100, "百"), (10, "十")):
        digit, n = divmod(n, value)
        if digit:
            out.append(("" if digit == 1 else _KANJI_DIGITS[digit]) + unit)
    if n:
        out.append(_KANJI_DIGITS[n])
    return "".join(out)


def japanese(n: int) -> str:
    """``n`` (0 to :data:`MAX_NUMBER`) in kanji numerals: 472619 -> 四十七万二千六百十九
    (1 before 十, 百, 千 unwritten; 一万 written, as in 一万二千)."""
    if not 0 <= n <= MAX_NUMBER:
        raise ValueError(f"{n} is outside 0-{MAX_NUMBER}")
    if n == 0:
        return _KANJI_DIGITS[0]
    oku, rest = divmod(n, 100_000_000)
    man, rest = divmod(rest, 10_000)
    text = ""
    if oku:
        text += _kanji_below_10000(oku) + "億"
    if man:
        text += ("一" if man == 1 else _kanji_below_10000(man)) + "万"
    return text + _kanji_below_10000(rest)


def in_words(n: int, lang: str) -> str:
    """``n`` in the words of ``lang`` (``ja``: kanji numerals; otherwise English)."""
    return japanese(n) if lang == "ja" else english(n)


__all__ = ["english", "japanese", "in_words", "MAX_NUMBER"]
