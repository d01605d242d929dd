"""AES-CMAC written out from RFC 4493 (subkeys by doubling in GF(2^128), 10* padding, CBC) over AES-128 in ECB
mode: an implementation independent of the cmac module hil.link.secoc uses, checked against the RFC's vectors."""

from cryptography.hazmat.primitives.ciphers import Cipher, algorithms, modes

BLOCK = 16
RB = 0x87
RFC4493_KEY = bytes.fromhex("2b7e151628aed2a6abf7158809cf4f3c")
RFC4493_SUBKEYS = (bytes.fromhex("fbeed618357133667c85e08f7236a8de"),
                   bytes.fromhex("f7ddac306ae266ccf90bc11ee46d513b"))
_M = bytes.fromhex(
    "6bc1bee22e409f96e93d7e117393172aae2d8a571e03ac9c9eb76fac45af8e51"
    "30c81c46a35ce411e5fbc1191a0a52eff69f2445df4f9b17ad2b417be66c3710"
)
RFC4493_EXAMPLES = (  # (message, AES-CMAC) of RFC 4493 section 4, examples 1-4
    (_M[:0], bytes.fromhex("bb1d6929e95937287fa37d129b756746")),
    (_M[:16], bytes.fromhex("070a16b46b4d4144f79bdd9dd04a287c")),
    (_M[:40], bytes.fromhex("dfa66747de9ae63030ca32611497c827")),
    (_M[:64], bytes.fromhex("51f0bebf7e3b9d92fc49741779363cfe")),
)


def _aes(key: bytes, block: bytes) -> bytes:
    encryptor = Cipher(algorithms.AES(key), modes.ECB()).encryptor()
    return encryptor.update(block) + encryptor.finalize()


def _xor(a: bytes, b: bytes) -> bytes:
    return bytes(x ^ y for x, y in zip(a, b, strict=True))


def _double(block: bytes) -> bytes:
    value = int.from_bytes(block, "big") << 1
    if value >> 128:
        value = (value & ((1 << 128) - 1)) ^ RB
    return value.to_bytes(BLOCK, "big")


def subkeys(key: bytes) -> tuple[bytes, bytes]:
    k1 = _double(_aes(key, bytes(BLOCK)))
    return k1, _double(k1)


def cmac(key: bytes, message: bytes) -> bytes:
    k1, k2 = subkeys(key)
    n = max(1, -(-len(message) // BLOCK))
    last = message[BLOCK * (n - 1) :]
    padded = (last + b"\x80" + bytes(BLOCK))[:BLOCK]  # 10* padding of a short last block
    last = _xor(last, k1) if len(last) == BLOCK else _xor(padded, k2)
    x = bytes(BLOCK)
    for i in range(n - 1):
        x = _aes(key, _xor(x, message[BLOCK * i : BLOCK * (i + 1)]))
    return _aes(key, _xor(x, last))
