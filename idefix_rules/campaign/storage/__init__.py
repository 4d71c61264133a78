"""The results file as the campaign writes it (``store``), safely: an undo journal
(``journal``), new versions swapped in whole (``revision``), one owner per output folder
(``ownership``) and the free space checked before every write (``diskspace``)."""
