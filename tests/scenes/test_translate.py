"""Foreign requests read as English: rooms, homes and common objects in Spanish, French,
German and Chinese; English words that are foreign words too stay English."""

from __future__ import annotations

import pytest

from factory.scenes.translate import translate

OBJECTS = ("mug", "bowl", "table", "chair", "bed", "sofa", "plate", "bottle", "lamp", "book")
OBJECTS_MORE = ("apple", "refrigerator")


@pytest.mark.parametrize(
    ("language", "text"),
    [
        (
            "es",
            "una taza, un cuenco, una mesa, una silla, una cama, un sofá, un plato, "
            "una botella, una lámpara, un libro, una manzana y una nevera",
        ),
        (
            "fr",
            "une tasse, un bol, une table, une chaise, un lit, un canapé, une assiette, "
            "une bouteille, une lampe, un livre, une pomme et un frigo",
        ),
        (
            "de",
            "eine Tasse, eine Schüssel, ein Tisch, ein Stuhl, ein Bett, ein Sofa, ein "
            "Teller, eine Flasche, eine Lampe, ein Buch, ein Apfel und ein Kühlschrank",
        ),
        ("zh", "杯子、碗、桌子、椅子、床、沙发、盘子、瓶子、灯、书、苹果和冰箱"),
    ],
)
def test_common_objects(language: str, text: str) -> None:
    tr = translate(text)
    assert tr.language == language and not tr.unknown, tr
    words = tr.text.replace(",", " ").split()
    assert all(o in words for o in OBJECTS + OBJECTS_MORE), tr.text


@pytest.mark.parametrize(
    ("text", "english"),
    [
        ("cocina", "kitchen"),
        ("cuisine", "kitchen"),
        ("Küche", "kitchen"),
        ("厨房", "kitchen"),
        ("dormitorio", "bedroom"),
        ("chambre à coucher", "bedroom"),
        ("Schlafzimmer", "bedroom"),
        ("卧室", "bedroom"),
        ("sala de estar", "living room"),
        ("salle de séjour", "living room"),
        ("Wohnzimmer", "living room"),
        ("客厅", "living room"),
        ("cuarto de baño", "bathroom"),
        ("salle de bains", "bathroom"),
        ("Badezimmer", "bathroom"),
        ("卫生间", "bathroom"),
        ("oficina", "office"),
        ("bureau à domicile", "home office"),
        ("Büro", "office"),
        ("办公室", "office"),
    ],
)
def test_room_words(text: str, english: str) -> None:
    assert translate(text).text == english


def test_english_is_left_alone() -> None:
    for text in ("a dimly lit bedroom", "a bad day in the den", "die cast toys on a regal table"):
        tr = translate(text)
        assert tr.text == text and tr.language == "en" and not tr.words and not tr.unknown
    assert translate("a bedroom with a cama").text == "a bedroom with a bed"


def test_unknown_words_are_named() -> None:
    tr = translate("una cocina con una tostadora")
    assert tr.language == "es" and tr.unknown == ("tostadora",)
    assert "'tostadora'" in tr.warning and "Spanish" in tr.warning
    assert translate("un café moderne", known=lambda w: False).unknown == ()
